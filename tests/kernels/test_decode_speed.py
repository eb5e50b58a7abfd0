"""The fast MLVQ decode (kernels/include/btf_packed.h): its interleaved tables are exact copies
of the originals (the flattened pdf4 → pdf3 scale: one rounding), its polynomial angle maths is
accurate, the batched kernel (eval_mlvq) gives eval_btf's values bit for bit, and the device
decode agrees with the numpy reference where float32 is hardest (grazing light, β → ±90°; the
view pole)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import random_queries, shared_material

from btf_addon.core.codecs.dense import DenseBTF
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.codecs.packed import INT_SLOT, pack
from btf_addon.core.grid import UBO2003

pytestmark = pytest.mark.opencl


@pytest.fixture(scope="module")
def alu():
    return MLVQBTF.from_directory(shared_material("alu"))


def test_fast_tables_are_exact_copies(alu):
    p = pack(alu)
    ints, floats = p.ints.ravel(), p.floats.ravel()
    t = alu.t

    def at(slot, n, k):
        start = int(ints[INT_SLOT[slot]])
        return floats[start : start + n * k].reshape(n, k)

    f6 = at("f_mlvq6", t["pdf6_scale"].size, 2)
    np.testing.assert_array_equal(f6[:, 0], t["pdf6_scale"].ravel())
    np.testing.assert_array_equal(f6[:, 1], t["pdf6_slices"].ravel())
    f4 = at("f_mlvq4", t["pdf4_scale"].size, 2)
    np.testing.assert_array_equal(f4[:, 1], t["pdf4_slices"].ravel())
    f3 = at("f_mlvq3", t["pdf3_scale"].size, 4)
    np.testing.assert_array_equal(f3[:, 0], t["pdf3_scale"].ravel())
    np.testing.assert_array_equal(f3[:, 1:3], t["pdf2_indices"][t["pdf3_slices"].ravel()])
    assert int(ints[INT_SLOT["f_mlvq3"]]) % 4 == 0  # float4 rows never straddle a 16-byte line
    f2 = at("f_mlvq2", t["pdf2_scale"].size, 2)
    np.testing.assert_array_equal(f2[:, 0], t["pdf2_scale"].ravel())
    np.testing.assert_array_equal(f2[:, 1], t["pdf2_slices"].ravel())
    ab = at("f_mlvq_ab", t["index_ab"].size, 2)
    np.testing.assert_array_equal(ab, t["ab_colors"][t["index_ab"].ravel()])
    n_slots, n_phi = t["pdf4_slices"].shape
    n_theta = t["pdf3_slices"].shape[1]
    f43 = at("f_mlvq43", n_slots * n_phi * n_theta, 4).reshape(n_slots, n_phi, n_theta, 4)
    assert int(ints[INT_SLOT["f_mlvq43"]]) % 4 == 0
    rows = t["pdf4_slices"]  # (slot, φ) → pdf3 row
    np.testing.assert_array_equal(f43[..., 1:3], t["pdf2_indices"][t["pdf3_slices"][rows]])
    np.testing.assert_array_equal(f43[..., 3], 0.0)
    # s4·s3 rounded once to float32 from the float64 product of the two float32 scales (what
    # the reference multiplies): within half an ulp, 2^-24 relative.
    want = t["pdf4_scale"][..., None].astype(np.float64) * t["pdf3_scale"][rows]
    np.testing.assert_allclose(f43[..., 0], want, rtol=2.0**-24, atol=0)


def test_grazing_light_and_view_pole_match_the_reference(alu, rng):
    from btf_addon.cl.context import OpenCLUnavailableError, create_context
    from btf_addon.cl.evaluate import device_btf

    try:
        ctx = create_context()
    except OpenCLUnavailableError as exc:
        pytest.skip(str(exc))
    n = 4000
    q = np.column_stack(
        [
            rng.random(n),
            rng.random(n),
            np.full(n, 90.0),
            rng.random(n) * 360,
            rng.random(n) * 90,
            rng.random(n) * 360,
        ]
    )
    q[: n // 2, 5] = q[: n // 2, 3] + 90.0 + rng.normal(0, 0.5, n // 2)  # β within ~1° of 90°
    q[n // 2 : n // 2 + 200, 4] = 0.0  # view at the pole
    got, want = device_btf(alu, ctx).evaluate_angles(q), alu.evaluate_angles(q)
    # float32 against float64: β and α come from atan2 of the turned light vector, accurate to
    # a few ulps even at β = ±90° (the original's asin is not), so the test's general bound
    # holds here too: 2e-4 of the largest value absolute, 2e-3 relative.
    np.testing.assert_allclose(got, want, rtol=2e-3, atol=2e-4 * float(want.max()))


@pytest.fixture(scope="module")
def cl_context():
    from btf_addon.cl.context import OpenCLUnavailableError, create_context

    try:
        return create_context()
    except OpenCLUnavailableError as exc:
        pytest.skip(str(exc))


def test_polynomial_angles_match_libm(cl_context):
    """btf_atan2_deg_xpos and btf_sincos_deg (branch-free polynomials) against float64 numpy
    over their whole ranges, poles and quadrant edges included."""
    import pyopencl as cl

    from btf_addon.cl.programs import KERNELS_DIR, build_defines, expand_includes

    source = "\n".join(
        [
            "__kernel void angles(__global const float *a, __global const float *b,",
            "                     __global float *out) {",
            "  int i = get_global_id(0); float c;",
            "  out[3 * i] = btf_atan2_deg_xpos(a[i], b[i]);",
            "  out[3 * i + 1] = btf_sincos_deg(a[i] * 400.0f, &c);",
            "  out[3 * i + 2] = c;",
            "}",
        ]
    )
    # the real program's source with a test kernel appended, built with the real defines
    text = expand_includes(KERNELS_DIR / "btf_eval.cl") + "\n" + source
    options = [f"-D{k}={v}" for k, v in sorted(build_defines({}).items())]
    prg = cl.Program(cl_context.context, text).build(options)
    y = np.concatenate([np.linspace(-1, 1, 20001), [0.0, 1.0, -1.0, 1e-8, -1e-8]])
    x = np.concatenate([np.sqrt(1 - np.linspace(-1, 1, 20001) ** 2), [0.0, 0.0, 0.0, 1.0, 1.0]])
    a, b = y.astype(np.float32), x.astype(np.float32)
    out = np.empty((len(a), 3), np.float32)
    mf = cl.mem_flags
    bufs = [
        cl.Buffer(cl_context.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=v) for v in (a, b)
    ]
    out_buf = cl.Buffer(cl_context.context, mf.WRITE_ONLY, out.nbytes)
    prg.angles(cl_context.queue, (len(a),), None, *bufs, out_buf)
    cl.enqueue_copy(cl_context.queue, out, out_buf)
    a64, b64 = a.astype(np.float64), b.astype(np.float64)
    # atan: the polynomial's 1.1e-7 rad plus float32 rounding of a value up to 90°: 2e-5°.
    np.testing.assert_allclose(out[:, 0], np.degrees(np.arctan2(a64, b64)), rtol=0, atol=2e-5)
    # sin, cos of angles up to ±400°: reduction in degrees is exact to float32 rounding of the
    # angle (2.4e-5° at 400° = 4e-7 rad), the polynomials < 3e-9: 1e-6 absolute.
    rad = np.radians(a64 * 400.0)
    np.testing.assert_allclose(out[:, 1], np.sin(rad), rtol=0, atol=1e-6)
    np.testing.assert_allclose(out[:, 2], np.cos(rad), rtol=0, atol=1e-6)


def test_vector_angles_equal_scalar_angles(cl_context):
    """The batched kernel's angle maths in float8 (btf_angles.inc built a second time) gives
    the float build's values bit for bit, over the whole range: poles, ±0, grazing light,
    quadrant edges of the sincos reduction, wrap-around of φ."""
    import pyopencl as cl

    from btf_addon.cl.programs import KERNELS_DIR, build_defines, expand_includes

    source = "\n".join(
        [
            "__kernel void angles(__global const float *a, __global const float *b,",
            "                     __global float *out) {",
            "  int i = get_global_id(0);",
            "  float8 a8 = vload8(i, a), b8 = vload8(i, b), c8;",
            "  vstore8(btf_atan2_deg_xpos8(a8, b8), 6 * i, out);",
            "  vstore8(btf_sincos_deg8(a8 * 400.0f, &c8), 6 * i + 1, out);",
            "  vstore8(c8, 6 * i + 2, out);",
            "  for (int k = 0; k < 8; k++) {",
            "    float c, y = a[8 * i + k], x = b[8 * i + k];",
            "    out[48 * i + 24 + k] = btf_atan2_deg_xpos(y, x);",
            "    out[48 * i + 32 + k] = btf_sincos_deg(y * 400.0f, &c);",
            "    out[48 * i + 40 + k] = c;",
            "  }",
            "}",
        ]
    )
    defines = build_defines({"MLVQ_BATCH": 8})
    text = expand_includes(KERNELS_DIR / "btf_eval.cl") + "\n" + source
    prg = cl.Program(cl_context.context, text).build([f"-D{k}={v}" for k, v in defines.items()])
    y = np.concatenate([np.linspace(-1, 1, 20001), [0.0, -0.0, 1.0, -1.0, 1e-8, -1e-8, 0.5]])
    x = np.concatenate([np.sqrt(1 - np.linspace(-1, 1, 20001) ** 2), [0, 0, 0, 0, 1, 1, -0.0]])
    y = np.concatenate([y, np.arange(-8, 9) * 22.5 / 400, [0.9, 0.9 + 1e-7]])  # quadrant edges
    x = np.concatenate([x, np.ones(19)])
    pad = -len(y) % 8
    a = np.concatenate([y, np.zeros(pad)]).astype(np.float32)
    b = np.concatenate([x, np.ones(pad)]).astype(np.float32)
    out = np.empty((len(a) // 8, 6, 8), np.float32)
    mf = cl.mem_flags
    bufs = [
        cl.Buffer(cl_context.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=v) for v in (a, b)
    ]
    out_buf = cl.Buffer(cl_context.context, mf.WRITE_ONLY, out.nbytes)
    prg.angles(cl_context.queue, (len(a) // 8,), None, *bufs, out_buf)
    cl.enqueue_copy(cl_context.queue, out, out_buf)
    assert np.isfinite(out).all()
    vector, scalar = out[:, :3].view(np.uint32), out[:, 3:].view(np.uint32)
    np.testing.assert_array_equal(vector, scalar)  # bits: -0.0 and 0.0 differ too


def assert_batched_equals_eval_btf(btf, cl_context, rng, n=1001):
    """The material's batched kernel gives eval_btf's values bit for bit, with a count that is
    no multiple of the batch or the group."""
    import pyopencl as cl

    from btf_addon.cl.evaluate import KernelEvaluator
    from btf_addon.core.angles import directions_from_angles_deg

    q = random_queries(rng, n)
    wi = directions_from_angles_deg(q[:, 2], q[:, 3])
    wo = directions_from_angles_deg(q[:, 4], q[:, 5])
    ev = KernelEvaluator(btf, cl_context)
    assert ev.batch >= 1 and ev.kernel.function_name != "eval_btf"  # a batched decode
    args = [ev._buffer(q), ev._buffer(np.stack([wi, wo], axis=1).reshape(-1, 3)), np.int32(n)]
    outs = []
    for kernel, size in (
        (cl.Kernel(ev.program, "eval_btf"), ((n,), None)),
        (ev.kernel, ev.launch_size(n)),
    ):
        out_buf = cl.Buffer(cl_context.context, cl.mem_flags.WRITE_ONLY, n * 12)
        kernel(cl_context.queue, *size, *args, ev._ints, ev._floats, out_buf)
        out = np.empty((n, 3), np.float32)
        cl.enqueue_copy(cl_context.queue, out, out_buf)
        outs.append(out)
    assert np.isfinite(outs[0]).all() and outs[0].any()
    np.testing.assert_array_equal(outs[1], outs[0])


@pytest.fixture(params=["cpu", "gpu"])
def launch(request, monkeypatch):
    """The batch a CPU launches (8 queries per work-item), or a GPU's (one per work-item, the
    scalar branch of the batched kernels), whatever the device here."""
    from btf_addon.cl import evaluate

    if request.param == "gpu":
        real = evaluate.batched_launch
        monkeypatch.setattr(evaluate, "batched_launch", lambda b, d: (real(b, d)[0], 1, None))
    return request.param


def test_batched_kernel_equals_eval_btf(alu, cl_context, rng, launch):
    """eval_mlvq (MLVQ_BATCH queries per work-item, levels interleaved) gives eval_btf's values
    bit for bit."""
    assert_batched_equals_eval_btf(alu, cl_context, rng)


def test_batched_dense_kernel_equals_eval_btf(cl_context, rng, launch):
    """eval_dense (DENSE_BATCH queries per work-item, every tap before any read) gives
    eval_btf's values bit for bit: random values at every (view, light, texel), θ past the
    last measured ring (the grazing factor) and the pole rings included."""
    n = len(UBO2003.directions())
    data = rng.random((n, n, 5, 7, 3), dtype=np.float32)
    assert_batched_equals_eval_btf(DenseBTF(data, UBO2003, UBO2003), cl_context, rng)


def test_standard_functions_branch_decodes_alike(alu, cl_context, rng, tmp_path, monkeypatch):
    """OpenCL compilers that are not clang get btf_builtins.h's standard functions instead of
    clang's builtins (PoCL is clang: the branch is built here with __clang__ undefined). Both
    are exact or correctly rounded, so the decode is the same to the last bit."""
    from btf_addon.cl import programs
    from btf_addon.cl.evaluate import device_btf

    q = random_queries(rng, 4001)
    want = device_btf(alu, cl_context).evaluate_angles(q)
    monkeypatch.setenv("BTF_CL_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(programs, "_memory_cache", {})
    expand = programs.expand_includes

    def without_clang(path, seen=None):
        text = expand(path, seen)
        return text if seen is not None else "#undef __clang__\n" + text  # the top file only

    monkeypatch.setattr(programs, "expand_includes", without_clang)
    got = device_btf(alu, cl_context).evaluate_angles(q)
    assert programs.stats["compiled"] >= 1  # built from the patched source, not a cache
    np.testing.assert_array_equal(got, want)

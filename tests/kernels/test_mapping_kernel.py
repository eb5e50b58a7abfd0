"""OpenCL's mapped lookup (kernels/include/btf_surface.h map_point + btf_mapped, via the
eval_mapped kernel) against the numpy reference core/mapping.py, for both mappings and both
texel filters."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import count_periods, shared_material, stripe_btf

from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.codecs.packed import pack
from btf_addon.core.mapping import mapped_evaluate
from btf_addon.scene.scene import Material, Mesh

pytestmark = pytest.mark.opencl


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def random_points(rng, n):
    """World points with a unit normal, an orthonormal mesh frame, uvs and directions above."""
    p = rng.uniform(-2, 2, size=(n, 3))
    nrm = _unit(rng.normal(size=(n, 3)))
    t = _unit(np.cross(nrm, rng.normal(size=(n, 3))))
    b = np.cross(nrm, t)
    uv = rng.uniform(-3, 3, size=(n, 2))

    def above():
        d = _unit(rng.normal(size=(n, 3)))
        return _unit(
            d
            + nrm
            * (
                np.abs(np.sum(d * nrm, axis=1, keepdims=True))
                + 0.05
                - np.sum(d * nrm, axis=1, keepdims=True)
            )
        )

    return p, nrm, t, b, uv, above(), above()


def cl_mapped(cl_context, btf, block, p, n, t, b, uv, wi, wo):
    import pyopencl as cl

    from btf_addon.cl.programs import build_program

    ctx = cl_context
    program = build_program(ctx.context, ctx.device, "btf_eval.cl", {})
    packed = pack(btf)
    mf = cl.mem_flags

    def buf(a):
        a = np.ascontiguousarray(a, dtype=np.float32).ravel()
        return cl.Buffer(ctx.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)

    rows = np.hstack([p, n, t, b, uv, wi, wo])
    out = np.empty((len(p), 3), dtype=np.float32)
    out_buf = cl.Buffer(ctx.context, mf.WRITE_ONLY, out.nbytes)
    kernel = cl.Kernel(program, "eval_mapped")
    kernel(
        ctx.queue,
        (len(p),),
        None,
        buf(rows),
        buf(block),
        np.int32(len(p)),
        buf(packed.ints),
        buf(packed.floats),
        out_buf,
    )
    cl.enqueue_copy(ctx.queue, out, out_buf)
    return out


@pytest.mark.parametrize("mapping", ["UV", "BOX"])
@pytest.mark.parametrize("texel_filter", ["NEAREST", "LINEAR"])
def test_opencl_mapping_matches_numpy(cl_context, rng, mapping, texel_filter):
    btf = MLVQBTF.from_directory(shared_material("alu"))
    mesh = Mesh(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 2)), np.zeros((3, 4)))
    c, s = np.cos(0.4), np.sin(0.4)
    mesh.world_from_object = np.array([[c, -s, 0, 0.2], [s, c, 0, 0.1], [0, 0, 1, 0], [0, 0, 0, 1]])
    material = Material(
        btf,
        uv_scale=1.7,
        uv_rotation_rad=0.3,
        uv_offset=(0.25, -0.1),
        mapping=mapping,
        texel_filter=texel_filter,
        box_blend=0.3,
    )
    block = material.block(0, mesh)
    args = random_points(rng, 2000)
    ref = mapped_evaluate(btf, block, *args)
    got = cl_mapped(cl_context, btf, block, *args)
    scale = float(np.abs(ref).mean())
    bad = np.abs(got - ref).max(axis=1) > 2e-3 * scale + 1e-6
    # float32 on the device: LINEAR is continuous in the coordinates, so every point agrees
    # (2e-3 of the mean value covers float32 angles and weights); NEAREST may pick the
    # neighbouring texel where a coordinate lies within float32 rounding of a texel edge
    # (≤ 1 % of random points).
    allowed = 0 if texel_filter == "LINEAR" else int(0.01 * len(bad))
    assert int(bad.sum()) <= allowed, (int(bad.sum()), np.abs(got - ref).max())


@pytest.mark.parametrize("mapping", ["UV", "BOX"])
def test_opencl_real_world_size_shows_the_expected_number_of_tiles(cl_context, mapping):
    """F12's side of tests/gl/test_mapping_render.py's tile count: a 0.5 m plane, 25 mm tile,
    UVs repeating 3× (real-world size must ignore them) → 20 stripe periods across."""
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.core.sampling.envmap import Environment, VirtualLights
    from btf_addon.scene.primitives import plane
    from btf_addon.scene.scene import Camera, Scene, look_at

    material = Material(stripe_btf(25.0), mapping=mapping, real_world=True, texel_filter="LINEAR")
    camera = Camera(look_at((0, 0, 3), (0, 0, 0), (0, 1, 0)), perspective=False, ortho_scale=0.5)
    black = Environment(np.zeros((4, 8, 3)))
    scene = Scene([plane(0.5, uv_repeats=3.0)], [material], camera, black)
    light = VirtualLights(np.array([[0.0, 0.0, 1.0]]), np.ones((1, 3)), np.ones(1))
    image = CLRenderer(scene, 256, 8, cl_context).render_direct(light).combined[..., :3]
    assert count_periods(image[4, :, 0]) == 20

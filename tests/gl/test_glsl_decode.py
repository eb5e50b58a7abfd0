"""The GLSL decoder (moderngl over EGL) against the numpy reference."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import random_queries, shared_material

from btf_addon.core.codecs import packed
from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF, PrincipledBTF
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.errors import UnsupportedBTFError
from btf_addon.gl import interface
from btf_addon.gl.interface import ShaderCompileError, ShaderInterface


@pytest.mark.parametrize("name", ["alu", "wallpaper"])
def test_glsl_decode_matches_numpy_within_one_8bit_step(gl_ctx, rng, name):
    """10⁴ random queries: |GLSL − numpy| ≤ 1/255 of the 8-bit scale the data was measured in
    (i.e. one raw decoder unit), the precision of the original images."""
    from btf_addon.gl.query import glsl_btf

    btf = MLVQBTF.from_directory(shared_material(name))
    q = random_queries(rng, 10_000)
    q[:20] = np.nan  # invalid rows never reach the shader
    got = glsl_btf(btf, gl_ctx).evaluate_angles(q)
    want = btf.evaluate_angles(q)
    assert np.all(got[:20] == 0)
    raw_error = np.abs(got - want) / btf.meta.value_scale
    assert raw_error.max() <= 1.0, raw_error.max()
    assert want.max() / btf.meta.value_scale > 100  # real, bright values were compared


@pytest.mark.parametrize(
    "btf",
    [
        LambertianBTF((0.8, 0.5, 0.2)),
        GGXBTF((0.9, 0.6, 0.3), 0.4),
        PrincipledBTF((0.9, 0.6, 0.3), 0.4, 0.3, 0.7),
    ],
    ids=["lambertian", "ggx", "principled"],
)
def test_glsl_analytic_presets_match(gl_ctx, rng, btf):
    from btf_addon.gl.query import glsl_btf

    q = random_queries(rng, 5_000)
    got, want = glsl_btf(btf, gl_ctx).evaluate_angles(q), btf.evaluate_angles(q)
    # single-precision GPU maths: 1e-3 relative, 1e-5 of the peak absolute
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-5 * float(want.max()))


def test_glsl_dense_matches(gl_ctx, rng):
    from btf_addon.core.codecs.dense import tabulate
    from btf_addon.core.grid import uniform_ring_grid
    from btf_addon.gl.query import glsl_btf

    btf = tabulate(
        woven(texels=4, fine_per_texel=4), uniform_ring_grid(20.0), uniform_ring_grid(15.0)
    )
    q = random_queries(rng, 5_000)
    got, want = glsl_btf(btf, gl_ctx).evaluate_angles(q), btf.evaluate_angles(q)
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-5 * float(want.max()))


def test_unsupported_codec_is_a_clear_error(gl_ctx):
    from btf_addon.gl.query import glsl_btf

    with pytest.raises(UnsupportedBTFError, match="GPU back ends"):
        glsl_btf(woven(texels=2, fine_per_texel=4), gl_ctx)


def test_shader_compile_error_is_readable(gl_ctx, tmp_path, monkeypatch):
    from btf_addon.gl.query import compile_program

    (tmp_path / "v.glsl").write_text("void main() { gl_Position = vec4(pos, 0.0, 1.0); }")
    (tmp_path / "f.glsl").write_text("void main() { frag_color = vec4(undefined_name); }")
    monkeypatch.setattr(interface, "SHADERS_DIR", tmp_path)
    broken = ShaderInterface(
        name="broken",
        vertex_inputs=((0, "VEC2", "pos"),),
        fragment_outputs=((0, "VEC4", "frag_color"),),
        samplers=(),
        vertex_file="v.glsl",
        fragment_file="f.glsl",
    )
    with pytest.raises(ShaderCompileError, match=r"(?s)'broken' failed to compile.*undefined_name"):
        compile_program(gl_ctx, broken)


def test_interface_limits_are_enforced():
    with pytest.raises(ValueError, match="samplers"):
        ShaderInterface(
            name="x",
            vertex_inputs=(),
            fragment_outputs=(),
            samplers=tuple((i, "FLOAT_2D", f"s{i}") for i in range(17)),
        )
    with pytest.raises(ValueError, match="push constants"):
        ShaderInterface(
            name="x",
            vertex_inputs=(),
            fragment_outputs=(),
            samplers=(),
            push_constants=(("MAT4", "a"), ("MAT4", "b"), ("VEC4", "c")),
        )


def _layout_probe(tmp_path) -> ShaderInterface:
    """The query shader's interface and libraries with a body that writes, at pixel i, the value
    the GLSL preprocessor gives the i-th layout macro."""
    names = list(packed.defines())
    values = ", ".join(names)
    (tmp_path / "probe_frag.glsl").write_text(
        "void main()\n{\n"
        f"  int values[{len(names)}] = int[{len(names)}]({values});\n"
        "  frag_color = vec4(float(values[int(gl_FragCoord.x)]), 0.0, 0.0, 1.0);\n}\n"
    )
    return dataclasses.replace(
        interface.QUERY_SHADER, name="layout_probe", fragment_file=str(tmp_path / "probe_frag.glsl")
    )


def test_glsl_sees_the_python_layout(gl_ctx, tmp_path):
    """Built the way every shader is (gl/interface.py), the layout macros hold exactly
    core/codecs/packed.py's numbers (integers below 2^24: exact in the float target)."""
    from btf_addon.gl.query import compile_program

    names = list(packed.defines())
    program = compile_program(gl_ctx, _layout_probe(tmp_path))
    quad = np.array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1], dtype=np.float32)
    vbo = gl_ctx.buffer(quad.tobytes())
    vao = gl_ctx.vertex_array(program, [(vbo, "2f", "pos")])
    target = gl_ctx.texture((len(names), 1), 4, dtype="f4")
    fbo = gl_ctx.framebuffer(color_attachments=[target])
    try:
        fbo.use()
        gl_ctx.viewport = (0, 0, len(names), 1)
        vao.render()
        pixels = np.frombuffer(fbo.read(components=4, dtype="f4"), dtype=np.float32)
    finally:
        for obj in (fbo, target, vao, vbo, program):
            obj.release()
    got = dict(zip(names, pixels.reshape(-1, 4)[:, 0].astype(int).tolist(), strict=True))
    assert got == packed.defines()


def test_glsl_refuses_to_build_without_the_layout(gl_ctx, tmp_path):
    """shaders/btf_tables_lib.glsl writes no slot number: a source without the layout defines
    stops at its #error instead of reading the wrong slots."""
    import moderngl

    vs, fs = _layout_probe(tmp_path).glsl_330()
    layout = tuple(f"#define {name} " for name in packed.defines())
    stripped = "\n".join(line for line in fs.splitlines() if not line.startswith(layout))
    assert len(stripped) < len(fs)  # the layout lines were there and are gone
    with pytest.raises(moderngl.Error, match="packed-layout defines missing"):
        gl_ctx.program(vertex_shader=vs, fragment_shader=stripped)


def test_an_evaluator_draws_in_its_own_context_after_another_was_made(gl_ctx, rng):
    """moderngl draws into whichever context is current: a second context made after the
    evaluator (another evaluator, a standalone renderer) must not receive its work."""
    from btf_addon.gl.query import create_gl_context, glsl_btf

    btf = GGXBTF((0.9, 0.6, 0.3), 0.4)
    q = random_queries(rng, 2_000)
    first = glsl_btf(btf, gl_ctx)
    other = create_gl_context()  # now current
    try:
        glsl_btf(LambertianBTF(0.5), other).evaluate_angles(q)
        got, want = first.evaluate_angles(q), btf.evaluate_angles(q)
    finally:
        other.release()
    # as test_glsl_analytic_presets_match
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-5 * float(want.max()))

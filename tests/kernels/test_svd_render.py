"""F12 with an svd material: the OpenCL final render and the GLSL viewport agree."""

from __future__ import annotations

import numpy as np
import pytest
from svd_cases import svd_cases

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.svd_build import factorise
from btf_addon.core.grid import uniform_ring_grid
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene.primitives import uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

pytestmark = pytest.mark.opencl


@pytest.mark.parametrize("case", ["ggx", "rotated-rings"])
def test_opencl_final_render_and_glsl_agree_on_an_svd_sphere(cl_context, gl_ctx, rng, case):
    """The same N virtual lights on a sphere: GLSL and OpenCL direct lighting agree within 2 %
    relative RMSE (the bound the MLVQ materials meet: rasteriser vs ray-cast interpolation of
    the normals, texel-edge picks). 'ggx': a tabulated GGX (one texel) as a rank-1 svd."""
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.gl.renderer import GLSLRenderer

    if case == "ggx":
        dense = tabulate(
            GGXBTF((0.9, 0.6, 0.3), 0.5), uniform_ring_grid(10.0), uniform_ring_grid(10.0)
        )
        btf, _ = factorise(dense.data * np.pi, dense.view_grid, dense.light_grid, ranks=(1, 1, 1))
    else:
        btf = svd_cases()[case]
    env = Environment(rng.gamma(0.6, 1.0, size=(32, 64, 3)) * [1.0, 0.9, 0.7])
    scene = Scene(
        [uv_sphere(1.0, segments=64, rings=32)],
        [Material(btf)],
        Camera(look_at((0.0, -4.0, 1.0), (0, 0, 0))),
        env,
    )
    lights = env.virtual_lights(32, seed=1)
    cl_image = CLRenderer(scene, 96, 72, cl_context).render_direct(lights).combined[..., :3]
    gl_image = GLSLRenderer(scene, 96, 72, gl_ctx).render(lights)
    assert gl_image.max() > 0
    err = float(np.sqrt(np.mean((cl_image - gl_image) ** 2)) / np.sqrt(np.mean(gl_image**2)))
    assert err < 0.02, err


def test_an_svd_btf_over_the_device_limit_traces_at_reduced_resolution(
    cl_context, rng, monkeypatch
):
    """A material whose tables exceed what the device takes renders a box-filtered copy with a
    note for the user (as the viewport does), instead of failing into the GLSL fallback with
    "OpenCL unavailable". The image equals rendering the reduced copy itself."""
    from btf_addon.cl import renderer as renderer_module
    from btf_addon.core.codecs.gpu_fit import fit_for_gpu

    grid = uniform_ring_grid(30.0)
    data = rng.uniform(0.1, 0.9, (grid.size, grid.size, 32, 32, 3)).astype(np.float32)
    svd, _ = factorise(data, grid, grid, ranks=(4, 2, 2))
    limit = 40_000  # bytes: the full tables (~48 kB) do not fit, a 16² copy does
    monkeypatch.setattr(renderer_module, "device_table_bytes", lambda _ctx: limit)
    camera = Camera(look_at((0.0, -4.0, 0.5), (0.0, 0.0, 0.0)))
    env = Environment(rng.gamma(0.7, 1.0, size=(16, 32, 3)))
    lights = env.virtual_lights(4, seed=1)
    mesh = uv_sphere(1.0, segments=24, rings=12)
    big = renderer_module.CLRenderer(
        Scene([mesh], [Material(svd)], camera, env), 32, 24, cl_context, film=None
    )
    assert len(big.notes) == 1 and "final render traces it at 16×16 texels" in big.notes[0]
    got = big.render_direct(lights).combined
    reduced, _ = fit_for_gpu(svd, 1 << 30, limit)
    want = (
        renderer_module.CLRenderer(
            Scene([mesh], [Material(reduced)], camera, env), 32, 24, cl_context, film=None
        )
        .render_direct(lights)
        .combined
    )
    np.testing.assert_array_equal(got, want)  # same data, same kernel: the same bits
    assert np.all(np.isfinite(got)) and got[..., :3].max() > 0

"""A BTF too large for the device's textures is drawn from a reduced copy, not a failed draw."""

from __future__ import annotations

import logging

import numpy as np

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.codecs.gpu_fit import fit_for_gpu
from btf_addon.core.codecs.svd_build import factorise
from btf_addon.core.grid import uniform_ring_grid
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene.primitives import uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

W, H = 48, 36


def _image(device, scene, lights):
    from btf_addon.gl.drawer import ProgressiveDrawer, ViewAccumulation

    drawer = ProgressiveDrawer(device, scene)
    view = ViewAccumulation(device, W, H)
    try:
        view.set_lights(lights, per_pass=4)
        drawer.restart(view, scene.camera.clip_from_world(W / H), scene.camera.shader_vector())
        drawer.add_batch(view)
        drawer.resolve(view)
        return view.read()[::-1, :, :3].copy()
    finally:
        view.release()
        drawer.release()


def test_an_svd_btf_over_the_texture_limit_draws_at_reduced_resolution(gl_ctx, rng, caplog):
    from btf_addon.gl.moderngl_device import ModernGLDevice

    grid = uniform_ring_grid(30.0)
    data = rng.uniform(0.1, 0.9, (grid.size, grid.size, 32, 32, 3)).astype(np.float32)
    svd, _ = factorise(data, grid, grid, ranks=(4, 2, 2))  # S·V 32² × 8 floats dominate
    camera = Camera(look_at((0.0, -4.0, 0.5), (0.0, 0.0, 0.0)))
    env = Environment(rng.gamma(0.7, 1.0, size=(16, 32, 3)))
    lights = env.virtual_lights(4, seed=1)
    device = ModernGLDevice(gl_ctx)
    device.max_texture_size = 2  # rows of TABLE_WIDTH floats: the full tables need 3
    scene = Scene([uv_sphere(1.0, segments=24, rings=12)], [Material(svd)], camera, env)
    with caplog.at_level(logging.WARNING, logger="btf_addon.gl.drawer"):
        got = _image(device, scene, lights)
    assert "viewport draws it at 16×16 texels instead of 32×32" in caplog.text
    # The same pixels as drawing the reduced copy itself (same GL operations, same data).
    reduced, _ = fit_for_gpu(svd, max_texture_size=2)
    device.max_texture_size = 16384
    want = _image(device, Scene(scene.meshes, [Material(reduced)], camera, env), lights)
    np.testing.assert_array_equal(got, want)
    assert np.all(np.isfinite(got)) and got.max() > 0
    other = _image(device, Scene(scene.meshes, [Material(LambertianBTF(0.5))], camera, env), lights)
    assert not np.array_equal(got, other)  # the svd material was drawn, not a fallback

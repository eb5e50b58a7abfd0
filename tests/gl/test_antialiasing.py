"""The viewport's anti-aliasing (issue 21): jitter per progressive pass through the film's
pixel filter converges to the filtered image, the one F12's Virtual Lights mode renders."""

from __future__ import annotations

import numpy as np
import pytest
from aa_scenes import H, W, edge_scene, expected_edge, rel_rmse

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.pixel_filter import PixelFilter
from btf_addon.scene.primitives import uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at


def test_jittered_passes_converge_to_the_filtered_edge(gl_ctx):
    """A black half-plane under a white World: after 64 one-light passes each pixel holds
    the filter's mass beyond the edge (as Cycles' film), within 0.03 (64 R2 offsets'
    stratification error); unjittered it is 0 or 1."""
    from btf_addon.gl.renderer import GLSLRenderer

    scene, edge_x = edge_scene()
    film = PixelFilter()
    lights = scene.environment.virtual_lights(64)
    renderer = GLSLRenderer(scene, W, H, gl_ctx)
    renderer.view.jitter = film
    jittered = renderer.render(lights, per_pass=1)[..., 0]
    expected = np.broadcast_to(expected_edge(film, edge_x), (H, W))
    np.testing.assert_allclose(jittered, expected, atol=0.03)
    renderer.view.jitter = None
    plain = renderer.render(lights, per_pass=1)[..., 0]
    assert np.abs(plain - expected).max() > 0.2
    renderer.release()


@pytest.mark.opencl
def test_converged_viewport_equals_the_virtual_lights_f12_with_the_same_filter(
    gl_ctx, cl_context, rng
):
    """A GGX sphere against a varied World, 64 lights one per pass (64 jitter offsets) against
    F12's Virtual Lights mode with 64 subpixels splitting the same lights: within 2 % relative
    RMSE (the issue's bound; measured 0.12 %: rasteriser vs ray-cast interpolation — the
    split-lights F12 takes the viewport's offsets in the viewport's order). Both are
    anti-aliased: the pixel-centre image differs from them far more."""
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.gl.renderer import GLSLRenderer

    env = Environment(rng.gamma(0.6, 1.0, size=(32, 64, 3)))
    cam = Camera(look_at((0.0, -4.0, 1.0), (0.0, 0.0, 0.0)))
    scene = Scene([uv_sphere(1.0, 64, 32)], [Material(GGXBTF((0.9, 0.6, 0.3), 0.4))], cam, env)
    lights = env.virtual_lights(64, seed=1)
    film = PixelFilter()
    w, h = 48, 36
    viewport = GLSLRenderer(scene, w, h, gl_ctx)
    viewport.view.jitter = film
    converged = viewport.render(lights, per_pass=1)
    f12 = CLRenderer(scene, w, h, cl_context, film=film)
    final = f12.render_direct(lights, aa_samples=64).combined[..., :3]
    centres = f12.render_direct(lights).combined[..., :3]
    error = rel_rmse(converged, final)
    print(f"viewport vs F12: {error:.4f}")  # quoted in docs/accuracy.md (pytest -s)
    assert error < 0.02
    assert rel_rmse(centres, final) > 2 * error
    viewport.release()


def test_a_still_eye_converges_jittered_and_restarts_when_the_film_changes(gl_ctx):
    """An eye (gl/eye.py) with the head still: each frame adds its K lights at the next
    subpixel offset, and after N/K frames it holds the jittered viewport's image exactly (same
    offsets, same order); turning anti-aliasing off restarts it at the pixel centres."""
    from btf_addon.gl.drawer import ProgressiveDrawer
    from btf_addon.gl.eye import EyeAccumulation
    from btf_addon.gl.moderngl_device import ModernGLDevice
    from btf_addon.gl.renderer import GLSLRenderer
    from btf_addon.render.lighting import frame_lights
    from btf_addon.render.settings import RenderSettings

    scene, _ = edge_scene()
    settings = RenderSettings(lights_total=8)
    cam = scene.camera
    clip_from_view = cam.projection(W / H)
    view_from_world = np.linalg.inv(cam.world_from_camera)
    device = ModernGLDevice(gl_ctx)
    drawer = ProgressiveDrawer(device, scene)
    eye = EyeAccumulation()
    restarts = [eye.advance(drawer, (W, H), settings, clip_from_view, view_from_world, 2)[1]]
    restarts += [
        eye.advance(drawer, (W, H), settings, clip_from_view, view_from_world, 2)[1]
        for _ in range(3)
    ]
    assert restarts == [True, False, False, False] and eye.view.batches == 4
    drawer.resolve(eye.view)
    eye_image = eye.view.read()[::-1, :, :3]
    reference = GLSLRenderer(scene, W, H, gl_ctx)
    reference.view.jitter = settings.film()
    lights = frame_lights(settings, scene, cam.world_from_camera[:3, 2])
    np.testing.assert_allclose(eye_image, reference.render(lights, per_pass=2), atol=1e-5)
    plain = RenderSettings(lights_total=8, use_antialiasing=False)
    assert eye.advance(drawer, (W, H), plain, clip_from_view, view_from_world, 2)[1]
    assert eye.view.jitter is None
    reference.release()
    eye.release()
    drawer.release()

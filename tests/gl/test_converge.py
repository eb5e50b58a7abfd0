"""One view drawn to convergence (gl/converge.py) on moderngl: the same pixels as the drawer's
restart / add_batch / resolve written out here, a cancel that stops after the batch it was
asked at and says so, and the three still-view callers (the standalone renderer, stereo
captures, F12's GLSL fallback) drawing through it with their own options and row orders."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.headsets import profile
from btf_addon.render.settings import RenderSettings
from btf_addon.scene.lights import PointLight
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

W, H = 48, 32
LIGHTS, PER_PASS = 20, 6  # batches of 6, 6, 6, 2
FILM = RenderSettings().film()  # Blackman-Harris, 1.5 px


def sphere_scene(rng) -> Scene:
    """A GGX sphere on a Lambertian ground, a point light, a random World: silhouettes
    against the World, so film and transparency both change pixels."""
    ground = plane(8.0, uv_repeats=4.0, material=1)
    ground.world_from_object = np.eye(4)
    ground.world_from_object[2, 3] = -1.0
    return Scene(
        [uv_sphere(1.0, segments=32, rings=16), ground],
        [Material(GGXBTF((0.9, 0.6, 0.3), 0.4)), Material(LambertianBTF(0.5), exposure=0.5)],
        Camera(look_at((0.0, -4.0, 0.3), (0.0, 0.0, 0.0)), clip_start=0.05, clip_end=50.0),
        Environment(rng.gamma(0.7, 1.0, size=(16, 32, 3))),
        lights=[PointLight(np.array([2.0, -2.0, 2.0]), np.array([20.0, 15.0, 10.0]))],
    )


@pytest.fixture
def scene(rng) -> Scene:
    return sphere_scene(rng)


@pytest.fixture
def drawer(gl_ctx, scene):
    from btf_addon.gl.drawer import ProgressiveDrawer
    from btf_addon.gl.moderngl_device import ModernGLDevice

    drawer = ProgressiveDrawer(ModernGLDevice(gl_ctx), scene)
    yield drawer
    drawer.release()


@pytest.fixture
def new_view(drawer, scene):
    """Views lit with the scene's first LIGHTS virtual lights, PER_PASS a batch."""
    from btf_addon.gl.drawer import ViewAccumulation

    views = []

    def make():
        view = ViewAccumulation(drawer.device, W, H)
        view.set_lights(scene.environment.virtual_lights(LIGHTS, seed=1), PER_PASS)
        views.append(view)
        return view

    yield make
    for view in views:
        view.release()


def pose(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    return scene.camera.clip_from_world(W / H), scene.camera.shader_vector()


def by_hand(drawer, view, scene, film, transparent, batches=None) -> np.ndarray:
    """The drawer's own steps: options, restart, ``batches`` batches (None: until none is
    left), resolve, read."""
    view.jitter, view.jitter_world = film, not transparent
    drawer.restart(view, *pose(scene))
    added = 0
    while (batches is None or added < batches) and drawer.add_batch(view):
        added += 1
    with drawer.device.bound(view.output):
        drawer.draw_resolved(view, transparent_background=transparent)
    return view.read()


@pytest.mark.parametrize("film", [None, FILM], ids=["centres", "film"])
@pytest.mark.parametrize("transparent", [False, True], ids=["opaque", "transparent"])
def test_converge_draws_the_pixels_of_the_steps_by_hand(drawer, new_view, scene, film, transparent):
    """Same GL operations in the same order → the same pixels, bit for bit; every light in,
    nothing stopped, the image bottom-first (h, w, 4) as the device reads it."""
    from btf_addon.gl.converge import converge

    drawn = converge(drawer, new_view(), *pose(scene), film=film, transparent=transparent)
    expected = by_hand(drawer, new_view(), scene, film, transparent)
    assert drawn.image.shape == (H, W, 4) and drawn.image.dtype == np.float32
    np.testing.assert_array_equal(drawn.image, expected)
    assert drawn.lights == LIGHTS and not drawn.stopped
    # The options reached the pixels: transparent leaves the World out (alpha 0 there).
    alpha = drawn.image[..., 3]
    assert (alpha == 0).any() if transparent else (alpha == 1).all()


def test_converge_ignores_the_options_a_view_had(drawer, new_view, scene):
    """A view left jittered without its World (an eye's last use) is drawn as asked."""
    from btf_addon.gl.converge import converge

    view = new_view()
    view.jitter, view.jitter_world = FILM, False
    drawn = converge(drawer, view, *pose(scene))
    np.testing.assert_array_equal(drawn.image, by_hand(drawer, new_view(), scene, None, False))


def test_a_progress_that_says_stop_ends_the_view_after_that_batch(drawer, new_view, scene):
    """The fractions after each batch; False at the second: two batches drawn and resolved,
    reported as stopped. False only after the last batch stops nothing."""
    from btf_addon.gl.converge import converge

    fractions = []

    def stop_at_second(fraction: float) -> bool:
        fractions.append(fraction)
        return len(fractions) < 2

    drawn = converge(drawer, new_view(), *pose(scene), film=FILM, progress=stop_at_second)
    assert fractions == [6 / 20, 12 / 20]
    assert drawn.stopped and drawn.lights == 2 * PER_PASS
    expected = by_hand(drawer, new_view(), scene, FILM, False, batches=2)
    np.testing.assert_array_equal(drawn.image, expected)

    fractions.clear()

    def stop_at_the_end(fraction: float) -> bool:
        fractions.append(fraction)
        return fraction < 1.0

    drawn = converge(drawer, new_view(), *pose(scene), progress=stop_at_the_end)
    assert fractions == [6 / 20, 12 / 20, 18 / 20, 1.0]
    assert not drawn.stopped and drawn.lights == LIGHTS


def test_converge_refuses_a_view_without_lights(drawer, scene):
    from btf_addon.gl.converge import converge
    from btf_addon.gl.drawer import ViewAccumulation

    view = ViewAccumulation(drawer.device, W, H)
    try:
        with pytest.raises(RuntimeError, match="lights first"):
            converge(drawer, view, *pose(scene))
    finally:
        view.release()


# --- the callers -----------------------------------------------------------------------------
def spy_on(monkeypatch, module) -> list:
    """Replace ``module``'s converge by one that records (keyword options, result)."""
    from btf_addon.gl.converge import converge

    calls = []

    def recording(*args, **kwargs):
        result = converge(*args, **kwargs)
        calls.append((kwargs, result))
        return result

    monkeypatch.setattr(module, "converge", recording)
    return calls


def test_the_standalone_renderer_converges_through_it(monkeypatch, gl_ctx, scene):
    """Its view's jitter is the film, the World stays; its image is row 0 at the top."""
    from btf_addon.gl import renderer

    calls = spy_on(monkeypatch, renderer)
    glsl = renderer.GLSLRenderer(scene, W, H, gl_ctx)
    try:
        glsl.view.jitter = FILM
        image = glsl.render(scene.environment.virtual_lights(LIGHTS, seed=1), per_pass=PER_PASS)
    finally:
        glsl.release()
    [(options, drawn)] = calls
    assert options["film"] is FILM and not options.get("transparent", False)
    assert drawn.lights == LIGHTS
    np.testing.assert_array_equal(image, drawn.image[::-1, :, :3])


def test_stereo_captures_converge_each_eye_through_it(monkeypatch, gl_ctx, scene):
    """One call per eye with the settings' film; the eyes' images are row 0 at the top."""
    from btf_addon.gl import stereo_capture
    from btf_addon.gl.moderngl_device import ModernGLDevice

    calls = spy_on(monkeypatch, stereo_capture)
    settings = RenderSettings(lights_total=LIGHTS, seed=1, aa_samples=4)
    prof = stereo_capture.capture_profile(profile("simulated"), 32)
    capture = stereo_capture.render_stereo(scene, settings, prof, ModernGLDevice(gl_ctx))
    assert len(calls) == 2
    for (options, drawn), eye in zip(calls, ("left", "right"), strict=True):
        assert options["film"] == settings.film() and not options.get("transparent", False)
        assert drawn.lights == LIGHTS and not drawn.stopped
        np.testing.assert_array_equal(capture.images[eye], drawn.image[::-1, :, :3])


class FakeEngine:
    """The few RenderEngine calls F12's fallback makes; Esc pressed at the ``esc_at``-th
    test_break."""

    def __init__(self, esc_at: int | None = None):
        self.esc_at, self.breaks, self.progress, self.reports = esc_at, 0, [], []

    def report(self, kind, message):
        self.reports.append(message)

    def update_stats(self, stats, info):
        pass

    def update_progress(self, fraction):
        self.progress.append(fraction)

    def test_break(self) -> bool:
        self.breaks += 1
        return self.esc_at is not None and self.breaks >= self.esc_at


def test_the_glsl_fallback_converges_through_it_and_cancels_on_esc(monkeypatch, gl_ctx, scene):
    """F12 without OpenCL: the film's jitter, a transparent film kept transparent, Blender's
    progress after each pass of 16 lights, Esc after the second pass: what was drawn, row 0 at
    the bottom (Blender's order)."""
    from btf_addon.blender import glsl_fallback

    calls = spy_on(monkeypatch, glsl_fallback)
    settings = RenderSettings(lights_total=40, seed=1)  # passes of 16, 16, 8
    engine = FakeEngine(esc_at=2)
    image = glsl_fallback.render_glsl(engine, scene, settings, W, H, transparent=True)
    assert engine.reports == []
    [(options, drawn)] = calls
    assert options["film"] == settings.film() and options["transparent"] is True
    assert drawn.stopped and drawn.lights == 32
    assert engine.progress == [16 / 40, 32 / 40]
    np.testing.assert_array_equal(image, drawn.image)


def test_no_caller_keeps_a_batch_loop_of_its_own():
    """Another loop over add_batch (or the renderer's render_pass) beside converge would be a
    second "draw to convergence" to keep in step."""
    for relative in ("gl/renderer.py", "gl/stereo_capture.py", "blender/glsl_fallback.py"):
        tree = ast.parse(Path(ROOT, "btf_addon", relative).read_text())
        for loop in (n for n in ast.walk(tree) if isinstance(n, ast.For | ast.While)):
            called = {
                c.func.attr
                for c in ast.walk(loop)
                if isinstance(c, ast.Call) and isinstance(c.func, ast.Attribute)
            }
            assert not called & {"add_batch", "render_pass"}, f"{relative}:{loop.lineno}"

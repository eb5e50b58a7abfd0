"""Stereo captures (gl/stereo_capture.py) on moderngl: each eye is the single-view render of
matrices built here from the profile's numbers, the eyes' disparity has the right sign and
size, the files hold [left | right] or one eye each with their JSON, oversized eyes are refused
before anything is drawn."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from helpers import read_png

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.errors import BTFError
from btf_addon.core.formats.imageio import read_exr
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.headsets import profile
from btf_addon.render.settings import Lighting, RenderSettings
from btf_addon.scene.lights import PointLight
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

EYE_WIDTH = 64  # small: the drawer's maths does not depend on the size
# Pixel centres: the geometry tests compare with un-jittered single views.
SETTINGS = RenderSettings(lights_total=24, seed=3, use_antialiasing=False)


def sphere_scene(rng, camera_pose: np.ndarray) -> Scene:
    """A GGX sphere on a Lambertian ground, a point light, a random environment."""
    ground = plane(8.0, uv_repeats=4.0, material=1)
    ground.world_from_object = np.eye(4)
    ground.world_from_object[2, 3] = -1.0
    return Scene(
        [uv_sphere(1.0, segments=32, rings=16), ground],
        [Material(GGXBTF((0.9, 0.6, 0.3), 0.4)), Material(LambertianBTF(0.5), exposure=0.5)],
        Camera(camera_pose, clip_start=0.05, clip_end=50.0),
        Environment(rng.gamma(0.7, 1.0, size=(16, 32, 3))),
        lights=[PointLight(np.array([2.0, -2.0, 2.0]), np.array([20.0, 15.0, 10.0]))],
    )


def frustum_projection(tangents: tuple[float, float, float, float], near, far) -> np.ndarray:
    """glFrustum from the near-plane extents (tan(angle) × near): written here from the
    OpenGL definition, not from render/headsets.py."""
    left, right, up, down = (t * near for t in tangents)
    return np.array(
        [
            [2 * near / (right - left), 0, (right + left) / (right - left), 0],
            [0, 2 * near / (up - down), (up + down) / (up - down), 0],
            [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
            [0, 0, -1, 0],
        ]
    )


def independent_eyes(head: np.ndarray, prof, near: float, far: float) -> dict:
    """{"left"/"right": (clip_from_world, eye position)} from the profile's numbers: the eye
    at ∓IPD/2 along the head's x axis, looking as the head does."""
    eyes = {}
    for name, side, fov in (("left", -1, prof.fov_left_eye), ("right", 1, prof.fov_right_eye)):
        position = head[:3, 3] + side * prof.ipd_m / 2 * head[:3, 0]
        rotation = head[:3, :3]
        view_from_world = np.eye(4)
        view_from_world[:3, :3] = rotation.T
        view_from_world[:3, 3] = -rotation.T @ position
        tangents = tuple(
            math.tan(a) for a in (fov.angle_left, fov.angle_right, fov.angle_up, fov.angle_down)
        )
        eyes[name] = (frustum_projection(tangents, near, far) @ view_from_world, position)
    return eyes


def single_view(
    device, scene, lights, clip_from_world, position, width, height, batch=None, film=None
):
    """One view through the drawer, lit by ``lights`` in batches of ``batch`` (None: the
    capture's un-jittered batch size), each batch at ``film``'s next subpixel offset."""
    from btf_addon.gl.drawer import ProgressiveDrawer, ViewAccumulation
    from btf_addon.gl.stereo_capture import BATCH

    drawer = ProgressiveDrawer(device, scene)
    view = ViewAccumulation(device, width, height)
    try:
        view.set_lights(lights, batch or BATCH)
        view.jitter = film
        drawer.restart(view, clip_from_world, [*position, 1.0])
        while drawer.add_batch(view):
            pass
        drawer.resolve(view)
        return view.read()[::-1, :, :3]
    finally:
        view.release()
        drawer.release()


def test_each_eye_is_the_single_view_render_of_the_profiles_eye(gl_ctx, rng):
    """The XTAL's asymmetric, mirrored per-eye frusta: each captured eye equals a single view
    drawn from matrices built in this test. Matrices agree to 1e-9 (float64 rounding of two
    formulas); the images are drawn with the same GL operations in the same order, so they
    may differ only where a float32 rounding of the uploaded matrix moves a silhouette pixel:
    at most 0.5 % of pixels, and the rest within 1e-5 relative."""
    from btf_addon.gl.moderngl_device import ModernGLDevice
    from btf_addon.gl.stereo_capture import capture_profile, render_stereo

    head = look_at((0.3, -4.0, 0.8), (0.0, 0.0, 0.0))
    scene = sphere_scene(rng, head)
    prof = capture_profile(profile("xtal-8k"), EYE_WIDTH)
    assert (prof.eye_width, prof.eye_height) == (64, 36)  # 16:9 kept
    device = ModernGLDevice(gl_ctx)
    capture = render_stereo(scene, SETTINGS, prof, device)
    expected = independent_eyes(head, prof, 0.05, 50.0)
    lights = scene.environment.virtual_lights(SETTINGS.lights_total, seed=SETTINGS.seed)
    assert capture.lights == 24
    for eye in capture.eyes:
        clip_from_world, position = expected[eye.name]
        np.testing.assert_allclose(eye.clip_from_world, clip_from_world, rtol=0, atol=1e-9)
        np.testing.assert_allclose(eye.position, position, rtol=0, atol=1e-12)
        reference = single_view(device, scene, lights, clip_from_world, position, 64, 36)
        got = capture.images[eye.name]
        assert got.shape == (36, 64, 3) and got.dtype == np.float32
        close = np.isclose(got, reference, rtol=1e-5, atol=1e-6).all(axis=-1)
        assert close.mean() >= 0.995, f"{eye.name}: {np.count_nonzero(~close)} pixels differ"
    # The two eyes really differ (different positions and frusta), so the check above means it.
    assert np.abs(capture.images["left"] - capture.images["right"]).max() > 0.05


def test_anti_aliased_eyes_split_the_lights_over_subpixels_as_f12(gl_ctx, rng):
    """With the film's filter (the default settings) each eye is the single view drawn with the
    lights split over ``aa_samples`` subpixel offsets, one per batch, as F12's Virtual Lights
    mode splits them: 24 lights over 8 subpixels → batches of 3. Same GL operations → same
    pixels (the 0.5 % silhouette allowance of the test above). The JSON says so, and the image
    is not the un-jittered one (silhouettes are softened)."""
    from btf_addon.gl.moderngl_device import ModernGLDevice
    from btf_addon.gl.stereo_capture import capture_profile, render_stereo

    settings = RenderSettings(lights_total=24, seed=3, aa_samples=8)
    head = look_at((0.3, -4.0, 0.8), (0.0, 0.0, 0.0))
    scene = sphere_scene(rng, head)
    prof = capture_profile(profile("xtal-8k"), EYE_WIDTH)
    device = ModernGLDevice(gl_ctx)
    capture = render_stereo(scene, settings, prof, device)
    lights = scene.environment.virtual_lights(24, seed=3)
    film = settings.film()
    assert capture.metadata("per-eye")["film"] == {
        "filter": film.type,
        "width_px": film.width,
        "subpixels": 8,
    }
    for eye in capture.eyes:
        position = np.linalg.inv(eye.view_from_world)[:3, 3]
        jittered = single_view(
            device, scene, lights, eye.clip_from_world, position, 64, 36, 3, film
        )
        centred = single_view(device, scene, lights, eye.clip_from_world, position, 64, 36)
        got = capture.images[eye.name]
        close = np.isclose(got, jittered, rtol=1e-5, atol=1e-6).all(axis=-1)
        assert close.mean() >= 0.995, f"{eye.name}: {np.count_nonzero(~close)} pixels differ"
        softened = ~np.isclose(got, centred, rtol=1e-3, atol=1e-4).all(axis=-1)
        assert softened.sum() > 20, eye.name  # the sphere's and ground's edges


def test_left_eye_sees_a_centred_object_further_right(gl_ctx):
    """A small sphere straight ahead of the head at distance d: in the left eye it lies right
    of where the right eye sees it, by f·IPD/d pixels (f = W / (tan r − tan l), the simulated
    profile's symmetric FOV). The centroids of the lit pixels match that within 1 pixel
    (the silhouette's rasterisation and the headlight's shading move a centroid by less)."""
    from btf_addon.gl.moderngl_device import ModernGLDevice
    from btf_addon.gl.stereo_capture import capture_profile, render_stereo

    distance, radius = 0.6, 0.08
    sphere = uv_sphere(radius, segments=48, rings=24)
    sphere.world_from_object = np.eye(4)
    sphere.world_from_object[1, 3] = distance  # the head looks along +y
    head = look_at((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    scene = Scene(
        [sphere],
        [Material(LambertianBTF(0.8))],
        Camera(head, clip_start=0.05, clip_end=10.0),
        Environment(np.zeros((4, 8, 3))),  # black World: only the sphere is lit
    )
    prof = capture_profile(profile("simulated"), 128)
    settings = RenderSettings(lighting=Lighting.HEADLIGHT)
    capture = render_stereo(scene, settings, prof, ModernGLDevice(gl_ctx))
    assert capture.lights == 1

    def centroid_x(image):
        weight = image.sum(axis=-1)
        assert weight.sum() > 0, "the sphere is not in view"
        return (weight.sum(axis=0) * np.arange(image.shape[1])).sum() / weight.sum()

    fov = prof.fov_left_eye
    focal_px = prof.eye_width / (math.tan(fov.angle_right) - math.tan(fov.angle_left))
    expected = focal_px * prof.ipd_m / distance
    disparity = centroid_x(capture.images["left"]) - centroid_x(capture.images["right"])
    assert disparity > 0
    assert abs(disparity - expected) < 1.0, (disparity, expected)


@pytest.fixture
def small_capture(gl_ctx, rng):
    from btf_addon.gl.moderngl_device import ModernGLDevice
    from btf_addon.gl.stereo_capture import capture_profile, render_stereo

    scene = sphere_scene(rng, look_at((0.0, -4.0, 0.5), (0.0, 0.0, 0.0)))
    prof = capture_profile(profile("simulated"), 40)  # 40×30 per eye
    return render_stereo(scene, SETTINGS, prof, ModernGLDevice(gl_ctx))


def test_side_by_side_file_is_left_then_right(small_capture, tmp_path):
    """EXR stores float32 losslessly: the file is exactly [left | right]; the JSON records
    the profile, IPD, FOVs, eye poses (∓IPD/2 along the head's x) and lights."""
    from btf_addon.gl.stereo_capture import write_stereo

    out = tmp_path / "shot.exr"
    written = write_stereo(small_capture, out, "side-by-side")
    assert written == [out, tmp_path / "shot.json"]
    image = read_exr(out)
    assert image.shape == (30, 80, 3)
    np.testing.assert_array_equal(image[:, :40], small_capture.images["left"])
    np.testing.assert_array_equal(image[:, 40:], small_capture.images["right"])
    meta = json.loads((tmp_path / "shot.json").read_text())
    assert meta["profile"]["name"] == "simulated" and meta["ipd_m"] == 0.063
    assert meta["eye_size"] == [40, 30] and meta["image_size"] == [80, 30]
    assert meta["lights"] == {"count": 24, "lighting": "environment", "seed": 3}
    assert meta["eyes"]["left"]["fov_rad"]["angle_left"] == -0.74
    poses = {k: np.array(v["world_from_eye"]) for k, v in meta["eyes"].items()}
    baseline = poses["right"][:3, 3] - poses["left"][:3, 3]
    np.testing.assert_allclose(baseline, [0.063, 0.0, 0.0], atol=1e-12)  # head x = world x
    assert meta["files"] == ["shot.exr"]
    assert not list(tmp_path.glob(".*tmp*"))  # atomic writes leave no temporaries


def test_per_eye_files_and_png(small_capture, tmp_path):
    """Per-eye EXRs hold one eye each; per-eye PNGs are the eyes through core/imageio's sRGB
    curve, byte for byte."""
    from btf_addon.core.formats.imageio import srgb8_from_linear
    from btf_addon.gl.stereo_capture import write_stereo

    written = write_stereo(small_capture, tmp_path / "pair.exr", "per-eye")
    assert [p.name for p in written] == ["pair_left.exr", "pair_right.exr", "pair.json"]
    for name in ("left", "right"):
        np.testing.assert_array_equal(
            read_exr(tmp_path / f"pair_{name}.exr"), small_capture.images[name]
        )
    assert json.loads((tmp_path / "pair.json").read_text())["image_size"] is None

    written = write_stereo(small_capture, tmp_path / "pair.png", "per-eye")
    assert [p.name for p in written] == ["pair_left.png", "pair_right.png", "pair.json"]
    for name in ("left", "right"):
        png = read_png(tmp_path / f"pair_{name}.png")
        assert png.shape == (30, 40, 3)
        np.testing.assert_array_equal(png, srgb8_from_linear(small_capture.images[name]))


def test_sizes_and_names_refused_before_drawing(tmp_path):
    """Eyes above the drawer's MAX_SIZE, a zero width, an unknown layout or suffix: a
    BTFError before any context is made (``device`` is a sentinel that would fail if used)."""
    from btf_addon.gl.drawer import MAX_SIZE
    from btf_addon.gl.stereo_capture import capture_profile, output_paths, render_stereo

    xtal = profile("xtal-8k")
    with pytest.raises(BTFError, match="larger than"):
        capture_profile(xtal, MAX_SIZE + 1)
    with pytest.raises(BTFError, match="at least 1"):
        capture_profile(xtal, 0)
    assert capture_profile(xtal).eye_width == 3840  # default: the profile's own size
    too_big = replace(xtal, eye_width=MAX_SIZE + 1)
    with pytest.raises(BTFError, match="larger than"):
        render_stereo(None, SETTINGS, too_big, device=object())
    with pytest.raises(BTFError, match="layout"):
        output_paths(tmp_path / "a.exr", "top-bottom")
    with pytest.raises(BTFError, match=r"\.exr or \.png"):
        output_paths(tmp_path / "a.jpg", "per-eye")

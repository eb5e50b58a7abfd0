"""Adaptive sampling of the Sampled render (issue 33; render/adaptive.py, the half buffer of
kernels/render_direct.cl ``render_env_mis``).

A scene whose upper half is a flat World (every sample of a pixel there sees the same colour:
no noise at all) and whose lower half is a glossy sphere on a diffuse ground (noise that 64
samples do not remove). With adaptive sampling the World stops at the minimum samples, the
surface takes (almost) every sample, and the image is as close to a high-sample reference as
the image without it; with nothing converging the image is the one without adaptive sampling,
bit for bit (the fixed launch split: the same float sums)."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.accuracy.ladder import relative_rmse
from btf_addon.render.adaptive import min_samples
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

pytestmark = pytest.mark.opencl

W, H = 32, 24
SAMPLES = 64
BOUNCES = 2
THRESHOLD = 0.005  # low enough that the surface's noise keeps it sampling (measured: all)


def _scene() -> Scene:
    ground = plane(8.0, material=1)
    ground.world_from_object = np.eye(4)
    ground.world_from_object[2, 3] = -1.0
    sky = np.empty((32, 64, 3), np.float32)
    sky[:] = (0.5, 0.6, 0.8)  # flat: a pixel that sees only the World has no noise
    return Scene(
        [uv_sphere(0.8, 24, 12), ground],
        [Material(GGXBTF(0.8, 0.3)), Material(LambertianBTF(0.7))],
        Camera(look_at((0.0, -5.0, 0.0), (0, 0, -0.6))),
        Environment(sky),
    )


@pytest.fixture(scope="module")
def renderer(cl_context):
    from btf_addon.cl.renderer import CLRenderer

    r = CLRenderer(_scene(), W, H, cl_context)
    r.fixed_launch_split = True  # the same launches, so the same float sums, every render
    r.samples_per_camera_ray = 4  # F12's default: the half is counted in camera-ray groups
    return r


@pytest.fixture(scope="module")
def regions(renderer):
    """(world, surface): pixels at least 2 px from any surface (the film's footprint, 1.5 px
    wide, and the 3 × 3 neighbours an unconverged pixel keeps active) and pixels that are
    surface all over (Film › Transparent's alpha of 1)."""
    from btf_addon.render.adaptive import dilate

    renderer.transparent = True
    try:
        alpha = _render(renderer, 0.0, samples=16)[..., 3]
    finally:
        renderer.transparent = False
    world = ~dilate(dilate(alpha > 0))
    surface = alpha == 1.0
    assert world.sum() >= 150 and surface.sum() >= 300  # both halves are there
    return world, surface


@pytest.fixture(scope="module")
def reference(renderer):
    """2048 samples, another seed: its own noise is 1/sqrt(32) of a 64-sample render's."""
    return _render(renderer, 0.0, samples=2048, seed=99)[..., :3]


def _render(renderer, threshold: float, samples: int = SAMPLES, seed: int = 3, progress=None):
    renderer.adaptive_threshold = threshold
    try:
        return renderer.render_sampled(samples, seed, progress, max_bounces=BOUNCES)
    finally:
        renderer.adaptive_threshold = 0.0


def test_with_nothing_converged_the_image_is_the_one_without(renderer, monkeypatch):
    """Adaptive sampling with a rule that stops no pixel runs every other part of it (half
    sums, checks, the device mask, passes cut at the checks) and must change no bit: the sums
    are added as before and the per-pixel division is the per-row one of before. (A threshold
    alone cannot stop nothing here: the flat World's error is exactly 0.)"""
    from btf_addon.render.adaptive import AdaptiveSampling

    off = _render(renderer, 0.0)
    assert np.all(renderer.sample_counts == SAMPLES)
    checked = []

    def stop_none(self, active, *_args):
        checked.append(True)
        return active

    monkeypatch.setattr(AdaptiveSampling, "still_active", stop_none)
    never = _render(renderer, THRESHOLD)
    assert len(checked) == 3 and np.all(renderer.sample_counts == SAMPLES)  # at 16, 32, 48
    np.testing.assert_array_equal(never, off)


def test_the_flat_world_stops_early_and_the_surface_takes_every_sample(renderer, regions):
    world, surface = regions
    _render(renderer, THRESHOLD)
    counts = renderer.sample_counts
    first = min_samples(THRESHOLD, SAMPLES)
    assert first == 16  # Cycles' 64 for 0.005, capped at a quarter of 64 samples
    assert np.all(counts[world] == first), np.unique(counts[world])
    # Noise of a glossy sphere and a shadowed ground at 64 samples: the most keep sampling
    # (measured: all, seeds 3-5; at a threshold of 0.025, 92-94 %); a few calm ground pixels
    # may stop at a check.
    assert (counts[surface] == SAMPLES).mean() > 0.85
    assert set(np.unique(counts)) <= {16, 32, 48, 64}  # checks every 16 samples from 16


def test_the_error_stays_that_of_every_sample(renderer, regions, reference):
    """Against the 2048-sample reference, the adaptive image's relative RMSE is within 5 % of
    the full render's (measured 0–1.3 % over 4 seeds: the World it stops is exact, the surface
    pixels it stops are a few), and a pixel that took every sample is the full render's bit
    for bit (a sample's points depend only on its index)."""
    full = _render(renderer, 0.0)
    adaptive = _render(renderer, THRESHOLD)
    counts = renderer.sample_counts
    assert counts.mean() < 0.85 * SAMPLES  # it did save samples
    every = counts == SAMPLES
    np.testing.assert_array_equal(adaptive[every], full[every])
    full_error = relative_rmse(full[..., :3], reference)
    assert relative_rmse(adaptive[..., :3], reference) <= 1.05 * full_error


def test_a_higher_threshold_stops_sooner(renderer, reference):
    means, errors = [], []
    for threshold in (0.025, 0.05, 0.25):  # 0.005 and 0.01 both keep nearly every pixel
        image = _render(renderer, threshold)
        means.append(renderer.sample_counts.mean())
        errors.append(relative_rmse(image[..., :3], reference))
    assert means[0] > means[1] > means[2], means
    assert errors[2] > errors[0], errors  # the noise a high threshold keeps shows


def test_the_measured_split_checks_at_the_same_counts(renderer, regions):
    """Launches sized by measured time end their passes at the checks too."""
    world, _surface = regions
    renderer.fixed_launch_split = False
    try:
        _render(renderer, THRESHOLD)
    finally:
        renderer.fixed_launch_split = True
    counts = renderer.sample_counts
    assert np.all(counts[world] == 16) and set(np.unique(counts)) <= {16, 32, 48, 64}


def test_progress_follows_the_work_left_and_esc_stops(renderer):
    """Progress rises to 1 as the work of the pixels still sampling is done (a stopped pixel's
    samples are no longer waited for), and returning False stops with the samples so far."""
    seen = []
    _render(renderer, THRESHOLD, progress=lambda f: seen.append(f) or True)
    assert np.all(np.diff(seen) > 0) and seen[-1] == pytest.approx(1.0)
    image = _render(renderer, THRESHOLD, progress=lambda f: f < 0.5)
    counts = renderer.sample_counts
    assert 0 < counts.max() < SAMPLES and np.all(np.isfinite(image))


def test_previews_come_at_most_about_twice_a_pass_time(renderer, monkeypatch):
    """Adaptive sampling ends passes at its checks, often a few ms apart (here the fixed split's
    passes of FIXED_LAUNCH_SAMPLES end there too); the preview (a copy of the whole image into
    Blender) comes after the first pass, then only once half PASS_SECONDS have gone by since
    the last one: with a pass time of hours, one preview; with no time at all, one after every
    pass but the last (as without adaptive sampling)."""
    from btf_addon.render import launch

    shown = []

    def render_with_previews():
        shown.clear()
        renderer.adaptive_threshold = THRESHOLD
        try:
            renderer.render_sampled(SAMPLES, 3, max_bounces=BOUNCES, preview=shown.append)
        finally:
            renderer.adaptive_threshold = 0.0
        return len(shown)

    monkeypatch.setattr(launch, "PASS_SECONDS", 3600.0)
    assert render_with_previews() == 1
    monkeypatch.setattr(launch, "PASS_SECONDS", 1e-9)
    assert render_with_previews() == SAMPLES // launch.FIXED_LAUNCH_SAMPLES - 1

"""Adaptive sampling's rule (render/adaptive.py) and its launch plan (render/launch.py), with
numbers worked by hand from Cycles' definitions; no device."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.render.adaptive import AdaptiveSampling, dilate, min_samples, pixel_error
from btf_addon.render.launch import LaunchPlan


@pytest.mark.parametrize(
    ("threshold", "samples", "expected"),
    [
        (0.1, 4096, 32),  # Cycles' own comment: 0.1 → 32, 0.01 → 64, 0.001 → 128
        (0.01, 4096, 64),
        (0.001, 4096, 128),
        (0.01, 64, 16),  # capped at a quarter of the samples
        (0.5, 8, 4),  # at least 4
    ],
)
def test_min_samples_follow_cycles_automatic_rule(threshold, samples, expected):
    assert min_samples(threshold, samples) == expected


def test_checks_every_16_samples_from_the_minimum_and_before_the_last():
    plan = AdaptiveSampling(0.01, 64)  # minimum 16
    assert [n for n in range(65) if plan.checks_at(n)] == [16, 32, 48]
    assert plan.next_check(0) == 16 and plan.next_check(16) == 32 and plan.next_check(48) is None
    assert [n for n in range(101) if AdaptiveSampling(0.01, 100).checks_at(n)] == [
        32,
        48,
        64,
        80,
        96,
    ]
    assert AdaptiveSampling.for_render(0.0, 64) is None  # off
    assert AdaptiveSampling.for_render(0.01, 16) is None  # no check before the last sample


def test_pixel_error_is_cycles_formula():
    mean = np.array([[[0.25, 0.25, 0.25], [1.0, 1.0, 1.0]]], np.float32)
    half = np.array([[[0.30, 0.20, 0.25], [1.3, 1.0, 0.7]]], np.float32)
    error = pixel_error(mean, half)
    # Dim: the difference over sqrt(intensity) (0.1 / sqrt(0.75)); bright (R+G+B > 1): over the
    # intensity itself (0.6 / 3).
    np.testing.assert_allclose(error[0], [0.1 / (1e-4 + np.sqrt(0.75)), 0.6 / (1e-4 + 3.0)], 1e-5)


def test_a_pixel_stops_below_the_threshold_itself_as_in_cycles_kernel():
    """Cycles' kernel compares the error with the Noise Threshold unscaled (``error <
    threshold``): errors of 0.9 and 1.1 × the threshold, each pixel apart from the others
    (a 5 × 5 image, the noisy one in a corner so its 3 × 3 neighbours are known)."""
    plan = AdaptiveSampling(0.01, 64)
    h, w = 5, 5
    mean = np.full((h, w, 3), 0.25, np.float32)  # intensity 0.75: n = sqrt(0.75)
    half = mean.copy()
    unit = np.sqrt(0.75) + 1e-4  # a difference of `unit` summed over RGB is an error of 1
    half[..., 0] += 0.9 * 0.01 * unit  # every pixel: 0.9 × the threshold, converged
    half[0, 0, 0] = mean[0, 0, 0] + 1.1 * 0.01 * unit  # this one: 1.1 ×, not converged
    in_half, count = np.full((h, w), 8), np.full((h, w), 16)
    error = pixel_error(mean, half)
    assert error[0, 0] == pytest.approx(0.011, rel=1e-3)
    assert error[4, 4] == pytest.approx(0.009, rel=1e-3)
    after = plan.still_active(np.ones((h, w), bool), mean, half, in_half, count)
    expected = np.zeros((h, w), bool)
    expected[0:2, 0:2] = True  # the noisy pixel and its neighbours
    np.testing.assert_array_equal(after, expected)


def test_dilate_grows_by_one_pixel_every_way():
    mask = np.zeros((5, 6), bool)
    mask[0, 0] = mask[3, 3] = True
    grown = dilate(mask)
    expected = np.zeros_like(mask)
    expected[0:2, 0:2] = expected[2:5, 2:5] = True
    np.testing.assert_array_equal(grown, expected)


def test_an_unconverged_pixel_keeps_its_neighbours_and_stopped_pixels_stay_stopped():
    plan = AdaptiveSampling(0.01, 64)  # converged: error < 0.01
    h, w = 5, 5
    mean = np.full((h, w, 3), 0.2, np.float32)
    half = mean.copy()
    half[2, 2] += 0.1  # error 0.3 / sqrt(0.6) ≈ 0.39: noisy
    in_half, count = np.full((h, w), 8), np.full((h, w), 16)
    active = np.ones((h, w), bool)
    active[0, 4] = False  # stopped before, noisy now: stays stopped
    half[0, 4] += 0.1
    in_half[4, 0] = 0  # its half is empty: cannot be judged, goes on
    after = plan.still_active(active, mean, half, in_half, count)
    expected = np.zeros((h, w), bool)
    expected[1:4, 1:4] = True
    expected[3:5, 0:2] = True  # the unjudged pixel and its neighbours
    np.testing.assert_array_equal(after, expected)


def _run(plan: LaunchPlan, on_pass=None) -> list:
    steps = []
    for step in plan:
        plan.record(step, 1e-7 * max(step.pixels, 1) * step.samples)
        steps.append(step)
        if step.ends_pass and on_pass is not None:
            on_pass(plan, step.first_sample + step.samples)
    return steps


@pytest.mark.parametrize("fixed", [True, False])
def test_passes_end_at_the_checks_and_stopped_rows_are_not_launched(fixed):
    w, h, samples = 40, 30, 64
    schedule = AdaptiveSampling(0.01, samples)
    active = np.full(h, w)

    def stop_rows(plan, done):
        if schedule.checks_at(done):
            active[: done // 2] = 0  # rows stop as checks go by: 8, then 16, then 24
            plan.set_active_rows(active)

    plan = LaunchPlan(w, h, samples, fixed=fixed, next_check=schedule.next_check)
    steps = _run(plan, stop_rows)
    ends = {s.first_sample + s.samples for s in steps if s.ends_pass}
    assert {16, 32, 48, 64} <= ends  # every check is a pass end
    for s in steps:  # no launch after a check covers rows stopped at it
        passed = [n for n in (16, 32, 48) if n <= s.first_sample]
        stopped = passed[-1] // 2 if passed else 0
        assert s.row0 >= stopped and s.pixels == s.rows * w
    done = [s.done for s in steps]
    assert np.all(np.diff(done) > 0) and done[-1] == pytest.approx(1.0)


def test_without_checks_the_plan_is_the_one_of_before():
    """All rows active and no checks: the launches and their progress of the fixed split."""
    steps = _run(LaunchPlan(50, 700, 12, fixed=True))
    for s in steps:
        assert s.pixels == s.rows * 50
        assert s.done == (s.first_sample * 700 + (s.row0 + s.rows) * s.samples) / (12 * 700)
    assert [s.last for s in steps].count(True) == 1 and steps[-1].last

"""The final render's launch planning (render/launch.py), driven by simulated launch costs."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from btf_addon.render import launch
from btf_addon.render.launch import LaunchPlan


def run(plan: LaunchPlan, seconds_per_pixel_sample) -> list[launch.Launch]:
    """Execute a plan against a cost model: f(row) → seconds per pixel-sample of that row."""
    steps = []
    for step in plan:
        rows = np.arange(step.row0, step.row0 + step.rows)
        cost = float(np.sum([seconds_per_pixel_sample(r) for r in rows]))
        plan.record(step, cost * plan.width * step.samples)
        steps.append(step)
    return steps


def coverage(steps, height: int, samples: int) -> np.ndarray:
    """(height, samples) count of how often each row rendered each sample."""
    seen = np.zeros((height, samples), np.int64)
    for s in steps:
        seen[s.row0 : s.row0 + s.rows, s.first_sample : s.first_sample + s.samples] += 1
    return seen


@pytest.mark.parametrize(
    ("width", "height", "samples", "cost"),
    [
        (1920, 1080, 1, 1e-8),  # the deterministic mode: one sample, cheap pixels
        (640, 480, 256, 2e-7),  # Sampled mode
        (37, 1, 7, 1e-3),  # one row, expensive
        (4096, 3000, 64, 1e-9),  # wider than a band's rows allow
    ],
)
def test_every_pixel_sample_is_rendered_exactly_once(width, height, samples, cost):
    steps = run(LaunchPlan(width, height, samples), lambda _row: cost)
    assert np.all(coverage(steps, height, samples) == 1)
    done = [s.done for s in steps]
    assert np.all(np.diff(done) > 0) and done[-1] == pytest.approx(1.0)
    assert [s.last for s in steps] == [False] * (len(steps) - 1) + [True]
    for s in steps:  # a pass ends exactly where the image ends
        assert s.ends_pass == (s.row0 + s.rows == height)


def test_launches_are_sized_to_the_target_time():
    """After the first (measuring) launch, each launch is predicted to take at most
    LAUNCH_SECONDS, and at least half of it unless the image end, the band limit or the 2×
    growth rule cut it shorter (the model cost is exact here, so prediction = outcome)."""
    w, h, samples, cost = 800, 600, 64, 3e-7
    plan = LaunchPlan(w, h, samples)
    steps = run(plan, lambda _row: cost)
    first = steps[0]
    assert (first.rows, first.samples) == (
        min(h, launch.FIRST_LAUNCH_PIXELS // w, plan.max_rows),
        1,
    )
    seconds = [s.rows * w * s.samples * cost for s in steps]
    assert max(seconds[1:]) <= launch.LAUNCH_SECONDS * (1 + 1e-9)
    for (prev, s), t in zip(pairwise(steps), seconds[1:], strict=True):
        growth_limit = max(1, 2 * prev.rows * prev.samples // s.samples)
        cut = s.row0 + s.rows == h or s.rows in (plan.max_rows, growth_limit)
        assert cut or t >= 0.5 * launch.LAUNCH_SECONDS, (s, t)


def test_passes_follow_the_preview_cadence():
    """Each pass over the image is about PASS_SECONDS: at most that, and every sample count
    the cost allows (at least one sample per pass, however slow)."""
    w, h, samples, cost = 320, 240, 1000, 1e-6  # one sample over the image: 0.077 s
    steps = run(LaunchPlan(w, h, samples), lambda _row: cost)
    pass_samples = [s.samples for s in steps if s.ends_pass]
    assert pass_samples[0] == 1  # measured first
    per_pass = int(launch.PASS_SECONDS / (cost * w * h))
    assert all(n <= per_pass for n in pass_samples)
    assert pass_samples[1] == per_pass
    slow = run(LaunchPlan(w, h, 3), lambda _row: 1.0)  # a second per pixel-sample
    assert [s.samples for s in slow if s.ends_pass] == [1, 1, 1]
    assert all(s.rows == 1 for s in slow[1:])  # the smallest launch there is


def test_a_cheap_region_cannot_talk_a_launch_into_a_huge_one():
    """Sky rows 1000× cheaper than the object below them: launches grow at most 2× per step,
    so the first expensive rows do not arrive in one enormous launch."""
    w, h = 512, 2000
    steps = run(LaunchPlan(w, h, 1), lambda row: 1e-9 if row < 1000 else 1e-6)
    for prev, s in pairwise(steps):
        assert s.rows * s.samples <= max(1, 2 * prev.rows * prev.samples)
    worst = max(s.rows * w * s.samples * 1e-6 for s in steps if s.row0 + s.rows > 1000)
    assert worst <= 2 * launch.LAUNCH_SECONDS * 2  # at most one doubling past the target


def test_cost_is_a_decaying_maximum():
    plan = LaunchPlan(100, 100, 1)
    step = next(iter(plan))
    plan.record(step, 1.0)
    slow = plan.cost
    plan.record(step, 1e-3)  # a fast launch halves the estimate at most
    assert plan.cost == pytest.approx(0.5 * slow)
    plan.record(step, 10.0)  # a slow one counts at once
    assert plan.cost == pytest.approx(10.0 / (step.rows * 100))


def test_device_memory_holds_one_band():
    plan = LaunchPlan(10_000, 10_000, 4)
    assert plan.max_rows * 10_000 <= launch.BAND_PIXELS
    steps = run(plan, lambda _row: 1e-12)  # so cheap that only the band limits launches
    assert max(s.rows for s in steps) == plan.max_rows
    assert LaunchPlan(10**6, 5).max_rows == 1  # a row wider than a band still renders


def test_limits_are_read_when_a_plan_is_made(monkeypatch):
    """Tests and benchmarks change the module's limits; a plan made afterwards follows them."""
    monkeypatch.setattr(launch, "PASS_SECONDS", 1e-9)
    steps = run(LaunchPlan(40, 30, 8), lambda _row: 1e-6)
    assert [s.samples for s in steps if s.ends_pass] == [1] * 8

"""The fixed launch split (render/launch.py): the same launches whatever the timings."""

from __future__ import annotations

import numpy as np

from btf_addon.render import launch
from btf_addon.render.launch import LaunchPlan


def _launches(plan, seconds):
    out = []
    for i, step in enumerate(plan):
        out.append((step.row0, step.rows, step.first_sample, step.samples))
        plan.record(step, seconds(i))
    return out


def test_fixed_split_ignores_timings_and_covers_everything_once():
    rng = np.random.default_rng(0)
    w, h, samples = 300, 200, 10
    a = _launches(LaunchPlan(w, h, samples, fixed=True), lambda i: 1e-4)
    b = _launches(LaunchPlan(w, h, samples, fixed=True), lambda i: float(rng.uniform(0.01, 5)))
    assert a == b
    covered = np.zeros((h, samples), int)
    for row0, rows, first, count in a:
        assert count <= launch.FIXED_LAUNCH_SAMPLES
        assert rows * w <= max(launch.FIXED_LAUNCH_PIXELS, w)
        covered[row0 : row0 + rows, first : first + count] += 1
    assert np.all(covered == 1)
    # The measured split does depend on timings (why the option exists).
    c = _launches(LaunchPlan(w, h, samples, fixed=False), lambda i: 1e-4)
    d = _launches(LaunchPlan(w, h, samples, fixed=False), lambda i: 0.5)
    assert c != d


def test_environment_turns_the_fixed_split_on(monkeypatch):
    monkeypatch.setenv(launch.FIXED_ENV, "1")
    assert LaunchPlan(64, 64, 8).fixed
    assert not LaunchPlan(64, 64, 8, fixed=False).fixed
    monkeypatch.setenv(launch.FIXED_ENV, "0")
    assert not LaunchPlan(64, 64, 8).fixed

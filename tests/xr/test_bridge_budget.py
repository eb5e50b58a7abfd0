"""The eyes of one frame share one budget decision (issue 30 item 6: one ``FrameBudget`` per
eye let the eyes' K part, 256 lights per frame in one eye and 1 in the other): gl/eye.py
``SharedBudget`` on its own, then the bridge against the test runtime with eyes of unequal
cost."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.gl.eye import HeadsetEye, SharedBudget
from btf_addon.render.settings import RenderSettings

BUDGET_S = 0.05


class FakeClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_shared_budget_gives_both_eyes_the_same_k_under_unequal_costs(rng):
    """Left eye 0.4 ms per light, right 0.05 ms, 2 ms overhead, stalls now and then, the
    right eye sometimes converged (draws nothing): every frame both eyes get one K, which
    settles so that the frame holds the budget."""
    clock = FakeClock()
    shared = SharedBudget(BUDGET_S, clock)
    eyes = [HeadsetEye(None, BUDGET_S, clock, shared) for _ in range(2)]
    assert all(eye.budget is shared.budget for eye in eyes)
    cost = (4e-4, 5e-5)
    ks, times = [], []
    for frame in range(200):
        start = clock.t
        clock.t += 0.002 + (0.2 if rng.random() < 0.03 else 0.0)  # overhead, a rare stall
        frame_ks = []
        for index, eye in enumerate(eyes):
            k = eye.lights_this_frame(None, BUDGET_S)
            frame_ks.append(k)
            converged = index == 1 and frame % 17 == 16
            eye.drawn = 0 if converged else k
            clock.t += cost[index] * eye.drawn
        assert frame_ks[0] == frame_ks[1], (frame, frame_ks)
        ks.append(frame_ks[0])
        times.append(clock.t - start)
    assert max(ks) > 50  # it did grow: K ≈ (50 − 2) ms / 0.45 ms ≈ 106
    steady = [t for t in times[-50:] if t < 0.1]  # stalls aside
    assert np.median(steady) <= BUDGET_S * 1.02
    assert np.median(steady) >= BUDGET_S * 0.8


def test_an_eye_asking_twice_starts_a_new_frame():
    """No eye order or index is needed: a frame starts when an eye asks again."""
    clock = FakeClock()
    shared = SharedBudget(BUDGET_S, clock)
    left, right = (HeadsetEye(None, BUDGET_S, clock, shared) for _ in range(2))
    steps = []
    real_frame = shared.budget.frame
    shared.budget.frame = lambda drawn: steps.append(drawn) or real_frame(drawn)
    for order in ([left, right], [right, left], [left, right]):
        for eye in order:
            eye.lights_this_frame()
            eye.drawn = 3 if eye is left else 1
        clock.t += 0.01
    assert steps == [0, 2, 2]  # one decision per frame, fed the eyes' mean, rounded up


@pytest.fixture
def bridge_script(xr_runtime):
    from tests.xr.test_bridge import head, script

    script(xr_runtime, head=[head()], head_motion=[0.002, 0.002], capture_dir=None)
    return xr_runtime


def test_the_bridge_draws_the_same_lights_in_both_eyes_of_every_frame(bridge_script, rng):
    """The bridge with a fake clock: the left eye's draw costs 10 times the right's per
    light. Both eyes get the same K every frame, and K adapts (grows, then holds)."""
    from btf_addon.xr.bridge import XRBridge
    from tests.xr.test_bridge import settings, small_scene

    clock = FakeClock()
    bridge = XRBridge(
        small_scene(rng),
        RenderSettings(),
        settings(lights_total=256, budget_s=BUDGET_S),
        clock=clock,
    )
    real_draw = bridge._draw_eye
    per_light = (2e-3, 2e-4)

    def draw_eye(index, *args):
        drawn = real_draw(index, *args)
        clock.t += per_light[index] * bridge.eyes[index].drawn
        return drawn

    bridge._draw_eye = draw_eye
    bridge.start()
    seen = []
    try:
        while bridge.frames < 25:
            clock.t += 0.001
            assert bridge.run_frame()
            left, right = bridge.eyes
            if left.view is not None and right.view is not None:
                assert left.view.state.per_pass == right.view.state.per_pass
                assert left.drawn == right.drawn
                status = bridge.status.lights_per_frame
                assert status["left"] == status["right"]
                seen.append(left.drawn)
    finally:
        bridge.close()
    assert len(seen) >= 25
    assert max(seen) >= 8  # it grew from 1: (50 ms − overhead) / 2.2 ms ≈ 22 lights
    assert seen[-1] <= 25  # and holds the budget with the left eye's cost counted

"""Frame-budget controller (render/frame_budget.py) driven by an injected clock.

A simulated eye: each frame that draws k lights takes overhead + cost·k seconds, times
(1 + noise·N(0, 1)) from the seeded generator, and the controller sees only the clock. The
ideal K is floor((target − overhead) / cost), target = budget · (1 + tolerance).
"""

from __future__ import annotations

import itertools
import math
import re

import numpy as np
import pytest

from btf_addon.render.frame_budget import FrameBudget, view_moved

BUDGET = 0.011


class Eye:
    """A simulated eye with its clock: ``frame`` advances the clock by one frame's time."""

    def __init__(self, overhead: float, cost: float, noise: float, rng, paced: float = 0.0):
        self.overhead, self.cost, self.noise, self.rng, self.paced = (
            overhead,
            cost,
            noise,
            rng,
            paced,
        )
        self.now = 100.0
        self.drawn = 0  # lights drawn in the frame now running (reported at the next call)

    def clock(self) -> float:
        return self.now

    def frame(self, k: int) -> float:
        t = (self.overhead + self.cost * k) * (1 + self.noise * self.rng.standard_normal())
        if self.paced:  # a runtime that shows frames at a fixed period: whole periods only
            t = self.paced * math.ceil(t / self.paced - 1e-9)
        self.now += t
        return t

    def ideal(self, budget: FrameBudget) -> int:
        return max(1, math.floor((budget.target_s - self.overhead) / self.cost))


def run(budget: FrameBudget, eye: Eye, frames: int, drawn=None) -> tuple[list[int], list[float]]:
    """``frames`` frames; each draws K lights (or ``drawn(K)``). Returns K and the interval
    of each frame."""
    ks, ts = [], []
    for _ in range(frames):
        k = budget.frame(eye.drawn)
        eye.drawn = k if drawn is None else drawn(k)
        ks.append(k)
        ts.append(eye.frame(eye.drawn))
    return ks, ts


def band(eye: Eye) -> int:
    """How far from the ideal K may sit: ±1, or more where the noise of one interval at the
    budget (3σ) is worth more than one light: intervals cannot tell K apart more finely."""
    return max(1, math.ceil(3 * eye.noise * BUDGET * 1.02 / eye.cost))


CASES = [  # overhead s, cost s per light, relative noise: band ±1 unless said
    (0.002, 0.0003, 0.005),  # ideal 30
    (0.008, 0.0001, 0.0025),  # overhead-heavy: ideal 32
    (0.0005, 0.002, 0.03),  # expensive lights: ideal 5
    (0.001, 0.00005, 0.01),  # cheap lights: ideal 204, 3σ = 0.34 ms = 7 lights: band ±7
]


@pytest.mark.parametrize(("overhead", "cost", "noise"), CASES)
def test_converges_to_the_ideal_k_and_holds_the_budget(rng, overhead, cost, noise):
    eye = Eye(overhead, cost, noise, rng)
    budget = FrameBudget(BUDGET, eye.clock)
    ks, ts = run(budget, eye, 80)
    ideal, tol = eye.ideal(budget), band(eye)
    # ×2 growth from K = 1 reaches 204 in 8 frames; 15 leaves room for the first estimates
    settled = ks[15:]
    assert all(abs(k - ideal) <= tol for k in settled), (ideal, tol, ks)
    # The steady interval holds the target: its mean over the settled frames lies within the
    # target, and below it by no more than the lights the band allows plus 3σ of that mean.
    mean = float(np.mean(ts[15:]))
    slack = (tol + 1) * cost + 3 * noise * budget.target_s / math.sqrt(len(ts) - 15)
    assert budget.target_s - slack <= mean <= budget.target_s + 3 * noise * budget.target_s
    assert not budget.over_budget
    assert budget.frame_time_s == pytest.approx(mean, rel=4 * noise + 0.01)


def test_convergence_does_not_depend_on_the_noise_draw(rng):
    """The same claims for 20 independent noise sequences (children of the seeded generator):
    the controller, not a lucky draw, holds them."""
    for child in rng.spawn(20):
        for overhead, cost, noise in CASES[:3]:
            eye = Eye(overhead, cost, noise, child)
            budget = FrameBudget(BUDGET, eye.clock)
            ks, _ = run(budget, eye, 40)
            assert all(abs(k - eye.ideal(budget)) <= band(eye) for k in ks[15:]), ks
        eye.cost *= 3  # then a slowdown: one step down, no undershoot below the band
        ks, _ = run(budget, eye, 20)
        assert all(abs(k - eye.ideal(budget)) <= band(eye) for k in ks[2:]), ks


def test_grows_at_most_twice_per_frame_and_status_reads_well(rng):
    eye = Eye(0.001, 0.00005, 0.01, rng)
    budget = FrameBudget(BUDGET, eye.clock)
    assert re.fullmatch(r"1 light/frame · measuring \(11\.0 ms budget\)", budget.status())
    ks, _ = run(budget, eye, 30)
    assert ks[0] == 1
    assert all(b <= 2 * a for a, b in itertools.pairwise(ks))
    assert re.fullmatch(r"\d+ lights/frame · \d+\.\d of 11\.0 ms", budget.status())


@pytest.mark.parametrize("factor", [3.0, 1 / 6])
def test_reconverges_when_the_cost_changes(rng, factor):
    """A resolution or scene change multiplies the cost per light: K follows within a few
    frames (the model forgets with memory 0.8, about five frames)."""
    eye = Eye(0.002, 0.0003, 0.01, rng)
    budget = FrameBudget(BUDGET, eye.clock)
    run(budget, eye, 40)
    eye.cost *= factor
    ks, ts = run(budget, eye, 60)
    ideal, tol = eye.ideal(budget), band(eye)
    assert all(abs(k - ideal) <= tol for k in ks[12:]), (ideal, ks)
    # after a slowdown, at most the frames of one reaction run over the budget by > 25 %
    assert sum(t > 1.25 * budget.target_s for t in ts) <= 3


def test_never_below_one_and_says_when_over_budget(rng):
    eye = Eye(0.009, 0.004, 0.01, rng)  # overhead + one light = 13 ms > 11 ms
    budget = FrameBudget(BUDGET, eye.clock)
    ks, _ = run(budget, eye, 40)
    assert min(ks) == 1 and ks[-10:] == [1] * 10
    assert budget.over_budget
    m = re.fullmatch(r"over budget: 1 light/frame takes (\d+\.\d) ms of 11\.0 ms", budget.status())
    assert m, budget.status()
    # the quoted time is the model's for one light: the simulated 13 ms within 3σ (3 %)
    assert float(m.group(1)) == pytest.approx(13.0, rel=0.03)
    # the overhead alone over budget (a converged eye that still cannot keep up)
    eye2 = Eye(0.02, 0.0, 0.01, rng)
    heavy = FrameBudget(BUDGET, eye2.clock)
    run(heavy, eye2, 20, drawn=lambda k: 0)
    assert heavy.lights_per_frame == 1 and heavy.over_budget
    m = re.fullmatch(r"over budget: frames take (\d+\.\d) ms of 11\.0 ms unlit", heavy.status())
    assert m and float(m.group(1)) == pytest.approx(20.0, rel=0.03)  # 20 ms within 3σ


def test_converged_frames_keep_the_model(rng):
    """An eye that converged draws nothing: its frames show the overhead alone. When its view
    moves again the same K is right at once."""
    eye = Eye(0.002, 0.0003, 0.01, rng)
    budget = FrameBudget(BUDGET, eye.clock)
    run(budget, eye, 40)
    ideal, tol = eye.ideal(budget), band(eye)
    ks, ts = run(budget, eye, 100, drawn=lambda k: 0)
    assert all(abs(k - ideal) <= tol for k in ks)
    ks, ts = run(budget, eye, 10)  # moving again: full batches
    assert all(abs(k - ideal) <= tol for k in ks)
    assert max(ts) <= budget.target_s * 1.05  # no frame overruns by more than 3σ + a light


def test_from_converged_start_nothing_is_learnt_about_lights(rng):
    eye = Eye(0.002, 0.0003, 0.01, rng)
    budget = FrameBudget(BUDGET, eye.clock, k_start=4)
    run(budget, eye, 10, drawn=lambda k: 0)
    assert budget.lights_per_frame == 4  # nothing says what a light costs: K stays
    assert budget.model[1] is None
    assert budget.model[0] == pytest.approx(0.002, rel=0.03)  # the overhead, within 3σ


def test_a_stall_is_ignored_but_a_lasting_slowdown_is_not(rng):
    eye = Eye(0.002, 0.0003, 0.01, rng)
    budget = FrameBudget(BUDGET, eye.clock)
    run(budget, eye, 40)
    k_before, t_before = budget.lights_per_frame, budget.frame_time_s
    for stall in (2.0, 0.3, 0.06):  # Blender paused, a shader compile, a long GC pause
        eye.now += stall
        ks, _ = run(budget, eye, 3)
        assert all(abs(k - k_before) <= 1 for k in ks), (stall, ks)
        assert budget.frame_time_s == pytest.approx(t_before, rel=0.05)
    eye.overhead += 0.05  # every frame 50 ms slower from now on: two in a row are believed
    run(budget, eye, 4)  # held, believed with the next, then the model follows in one step
    assert budget.lights_per_frame == 1 and budget.over_budget


def test_a_paced_runtime_settles_without_repeated_overruns(rng):
    """A runtime that paces a 90 Hz display makes every interval a whole number of 11.1 ms
    periods: the intervals cannot show how long a frame took. K must stay on budget after
    the first probes and not keep missing frames."""
    eye = Eye(0.002, 0.0003, 0.02, rng, paced=1 / 90)
    budget = FrameBudget(BUDGET, eye.clock)
    ks, ts = run(budget, eye, 600)
    fits = math.floor((1 / 90 - eye.overhead) / eye.cost)  # the most lights a period holds
    assert sum(t > 1.5 / 90 for t in ts[20:]) <= 3  # ≤ 3 missed frames in 580 (6.4 s)
    assert 1 <= ks[-1] <= fits
    assert not budget.over_budget


def test_reset_forgets_timings_but_keeps_k(rng):
    eye = Eye(0.002, 0.0003, 0.01, rng)
    budget = FrameBudget(BUDGET, eye.clock)
    run(budget, eye, 30)
    k = budget.lights_per_frame
    budget.reset()
    assert budget.lights_per_frame == k and budget.frame_time_s is None
    assert budget.model is None and not budget.over_budget
    eye.now += 5.0  # the gap across the reset is not an interval
    budget.frame(k)
    assert budget.frame_time_s is None


def test_arguments_are_checked():
    with pytest.raises(ValueError, match="positive"):
        FrameBudget(0.0)
    with pytest.raises(ValueError, match="k_start"):
        FrameBudget(BUDGET, k_start=0)
    with pytest.raises(ValueError, match="lights_drawn"):
        FrameBudget(BUDGET).frame(-1)


def test_view_moved():
    rng = np.random.default_rng(5)
    m = rng.normal(size=(4, 4))
    assert view_moved(m, None) and view_moved(None, m)
    assert not view_moved(m, m.copy())
    scale = np.abs(m[:, :3]).max()
    tiny = m + rng.uniform(-1, 1, size=(4, 4)) * 1e-6 * scale  # tracking jitter
    assert not view_moved(m, tiny)
    moved = m.copy()
    moved[0, 1] += 1e-3 * scale
    assert view_moved(m, moved)
    assert view_moved(m, m + 2e-4 * scale) and not view_moved(m, m + 2e-4 * scale, 1e-3)
    # a far world origin (large translation column) does not hide a small turn of the view
    far = m.copy()
    far[:, 3] *= 1e5
    turned = far.copy()
    turned[:, :3] += 1e-3 * scale
    assert view_moved(far, turned)
    with pytest.raises(ValueError, match="4, 4"):
        view_moved(np.eye(3), np.eye(3))

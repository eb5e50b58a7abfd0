"""Frame-budget control: how many virtual lights (K) one eye adds per frame so that a stereo
frame holds a frame-time budget (11 ms for a 90 Hz headset), and when a view has moved.

Blender's ``gpu`` module has no timer query, so the only clock is the interval between
successive calls of the same eye's draw callback: it covers everything that happens between
them (this eye's K lights and resolve, the other eye, Blender's own drawing, the runtime's
frame pacing). ``frame(lights_drawn)`` is called at the start of each frame with the number
of lights added in the previous one, and returns K.

One ``FrameBudget`` per headset frame, shared by its eyes (gl/eye.py ``SharedBudget``: called
once per frame with the mean of the lights the eyes drew, the same K for every eye), so the
cost per light it fits is that of a light in every eye. One per eye, each called in its own
callback, sees the same intervals in a steady frame, but decides alone (its held spikes, its
ceiling, its probes): against a paced runtime the eyes' Ks parted, one at 256 lights per
frame and the other at 1 (issue 30 item 6).

The rule (one sample per call, the interval ``t`` of the frame that drew ``k`` lights):

1. **Outliers.** A ``t`` more than ``SPIKE_FACTOR`` (3) times the model's prediction and over
   the budget is held back: if the next interval is normal again it was a stall (Blender busy,
   the session paused, a shader compile) and is dropped; if the next one is slow too, both are
   kept: the scene really got slower, and the next ``TRUST_FRAMES`` (3) intervals are kept
   untested while the model learns the new times. Non-positive intervals (clock glitches) are
   dropped.
2. **Model.** ``t ≈ overhead + cost · k``, fitted by weighted least squares to the recent
   samples with forgetting (weight ``memory ** age``, ``memory`` = 0.8: about five frames of
   memory, so a change of scene or resolution is followed within a few frames). Frames with
   ``k`` = 0 (converged, nothing drawn) measure the overhead alone. Once the samples have
   spread over two or more K, the fit is remembered and enters later fits as two light
   pseudo-samples on its line (at k = 0 and at the current K): when K then stays put, the
   fresh samples at that K move the line while the remembered intercept keeps it determined.
   An interval more than ``CHANGE`` (25 %) off the prediction means the times changed (scene,
   resolution, load): the old samples are forgotten and the line pivots on its overhead
   through the new interval (a lit frame gives the new cost per light), so K follows a change
   in one step instead of averaging two regimes. Before any spread, the overhead is taken from
   ``k`` = 0 frames if there were any, else 0, so the first estimate of the cost is on the
   high side (K too small, never too large). A fit whose slope is not positive (more lights
   were not slower: a paced runtime, or the overhead moved under them) keeps the remembered
   cost, or leaves the cost unknown before there is one.
3. **Target.** ``target = budget · (1 + tolerance)``, ``tolerance`` = 0.02: a runtime that
   paces a 90 Hz display returns 11.1 ms intervals against the 11 ms default, which must count
   as on budget. K_fit = floor((target − overhead) / cost), clamped to [1, k_max].
4. **Step.** K grows to K_fit by at most ×2 per frame; it drops to K_fit at once. Before the
   model has seen two K, a frame that drew the full K within the target probes K + 1 (the
   high-side cost estimate alone would never try more); while the cost is unknown, a lit
   frame within the target doubles K and one over it scales K down in proportion. A frame
   more than 25 % over the target
   (a missed frame when the runtime paces frames, where the interval jumps to 2 periods and
   the straight-line model does not hold) sets a ceiling: K stays below the K that overran for
   ``CEILING_FRAMES`` accepted frames, so a paced session settles with a rare probe instead of
   overrunning every few frames. The ceiling goes earlier when the model predicts that K
   fits with room to spare (the scene got cheaper).
5. ``over_budget`` is true when the model says that even K = 1 takes longer than the target
   (before any light was drawn: when the frames without lights already do).

``view_moved`` compares two ``clip_from_world`` matrices: an eye's accumulation restarts when
its view changed by more than a tolerance relative to the matrix's scale.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable

import numpy as np

SPIKE_FACTOR = 3.0  # an interval this many times the prediction (and over budget) is suspect
OVERRUN_FACTOR = 1.25  # an interval this far over the target sets the ceiling (a missed frame)
CEILING_FRAMES = 240  # accepted frames a ceiling holds (about 2.7 s at 90 Hz)
WINDOW = 32  # samples kept; memory ** 32 is negligible for the default memory
PRIOR_WEIGHT = 0.3  # weight of each of the remembered line's two pseudo-samples
SMOOTHING = 0.3  # EWMA weight of the newest interval in ``frame_time_s``
TRUST_FRAMES = 3  # after two slow frames in a row, the next ones are believed without test
CHANGE = 0.25  # an interval this far (relative) from the prediction means the times changed
#: 90 Hz: the budget where no one reports the display's period (Blender's VR session never
#: says it; the XTAL bridge asks the runtime, then the headset profile).
DEFAULT_BUDGET_S = 0.011


class FrameBudget:
    """Lights per frame (K) for one eye from the intervals between its draw calls.

    ``budget_s``: the frame time to hold (seconds); ``clock``: seconds as a float, injectable
    for tests (``time.perf_counter`` by default); ``k_max``: the most lights per frame;
    ``k_start``: K for the first frames; ``memory`` in (0, 1): forgetting factor per sample;
    ``tolerance``: the fraction over the budget that still counts as on budget.
    """

    def __init__(
        self,
        budget_s: float = DEFAULT_BUDGET_S,
        clock: Callable[[], float] = time.perf_counter,
        *,
        k_max: int = 256,
        k_start: int = 1,
        memory: float = 0.8,
        tolerance: float = 0.02,
    ):
        if not budget_s > 0:
            raise ValueError(f"the frame budget must be positive, got {budget_s} s")
        if k_max < 1 or not 1 <= k_start <= k_max:
            raise ValueError(f"need 1 <= k_start ({k_start}) <= k_max ({k_max})")
        if not 0 < memory < 1:
            raise ValueError(f"memory must lie in (0, 1), got {memory}")
        if tolerance < 0:
            raise ValueError(f"tolerance must be >= 0, got {tolerance}")
        self.budget_s = float(budget_s)
        self.clock = clock
        self.k_max = int(k_max)
        self.memory = float(memory)
        self.tolerance = float(tolerance)
        self._k = int(k_start)
        self.reset()

    # --- public state ------------------------------------------------------------------------
    @property
    def lights_per_frame(self) -> int:
        """The current K (int >= 1)."""
        return self._k

    @property
    def frame_time_s(self) -> float | None:
        """Smoothed interval between successive accepted calls (seconds); None until one
        interval was measured."""
        return self._smoothed

    @property
    def target_s(self) -> float:
        """The longest interval that counts as on budget: budget · (1 + tolerance)."""
        return self.budget_s * (1.0 + self.tolerance)

    @property
    def model(self) -> tuple[float, float | None] | None:
        """The fitted (overhead_s, cost_s per light), cost None while the intervals have not
        shown what a light costs (only unlit frames so far, or no slope yet); None before
        any sample."""
        return self._fit

    @property
    def over_budget(self) -> bool:
        """True when the model predicts that even K = 1 takes longer than the target (or,
        before any light was drawn, that the frames without lights already do)."""
        t = self._slowest_allowed()
        return t is not None and t > self.target_s

    def _slowest_allowed(self) -> float | None:
        """Predicted seconds of a frame with one light; the overhead while no cost is known."""
        t1 = self._predict(1)
        return self._predict(0) if t1 is None else t1

    def status(self) -> str:
        """One line for the HUD or the panel."""
        budget_ms = self.budget_s * 1000
        if self.over_budget:
            t_ms = self._slowest_allowed() * 1000
            if self._predict(1) is None:
                return f"over budget: frames take {t_ms:.1f} ms of {budget_ms:.1f} ms unlit"
            return f"over budget: 1 light/frame takes {t_ms:.1f} ms of {budget_ms:.1f} ms"
        lights = f"{self._k} light{'s' if self._k != 1 else ''}/frame"
        if self._smoothed is None:
            return f"{lights} · measuring ({budget_ms:.1f} ms budget)"
        return f"{lights} · {self._smoothed * 1000:.1f} of {budget_ms:.1f} ms"

    def reset(self) -> None:
        """Forget all timings (a session (re)start); K is kept."""
        self._last_call: float | None = None
        self._samples: deque[tuple[int, float]] = deque(maxlen=WINDOW)
        self._held: tuple[int, float] | None = None
        self._trusting = 0  # frames accepted without the spike test after a confirmed change
        self._smoothed: float | None = None
        self._fit: tuple[float, float | None] | None = None
        self._prior: tuple[float, float] | None = None  # the last fit over spread samples
        self._ceiling: int | None = None
        self._ceiling_age = 0

    # --- the step ----------------------------------------------------------------------------
    def frame(self, lights_drawn: int) -> int:
        """Call at the start of each of this eye's frames; ``lights_drawn``: the lights this
        eye added in its previous frame (0: converged or nothing drawn). Returns K (>= 1)."""
        if lights_drawn < 0:
            raise ValueError(f"lights_drawn must be >= 0, got {lights_drawn}")
        now = float(self.clock())
        last, self._last_call = self._last_call, now
        if last is None:
            return self._k
        interval = now - last
        if not interval > 0:
            return self._k  # the clock did not advance: nothing to learn
        for sample in self._accept(int(lights_drawn), interval):
            self._add(sample)
        return self._k

    def _accept(self, k: int, t: float) -> list[tuple[int, float]]:
        """The samples this interval releases: none while a spike is held, the spike and this
        one when this one is slow too, only this one after a stall."""
        expected = self._predict(k)
        if expected is None:
            expected = self._smoothed if self._smoothed is not None else self.budget_s
        spike = t > SPIKE_FACTOR * expected and t > self.target_s
        held, self._held = self._held, None
        if held is not None:
            if spike:
                # two slow frames in a row: the scene really is slower, and the model will be
                # wrong for a few frames while it learns how: believe those frames too
                self._trusting = TRUST_FRAMES
                return [held, (k, t)]
            return [(k, t)]  # the held one was a stall: dropped
        if self._trusting:
            self._trusting -= 1
            return [(k, t)]
        if spike:
            self._held = (k, t)
            return []
        return [(k, t)]

    def _add(self, sample: tuple[int, float]) -> None:
        k, t = sample
        self._follow_change(k, t)
        self._samples.append(sample)
        a = SMOOTHING
        self._smoothed = t if self._smoothed is None else (1 - a) * self._smoothed + a * t
        if self._ceiling is not None:
            self._ceiling_age += 1
            if self._ceiling_age > CEILING_FRAMES:
                self._ceiling = None
        if k >= 1 and t > OVERRUN_FACTOR * self.target_s:
            if self._ceiling is None or k <= self._ceiling:
                self._ceiling, self._ceiling_age = k, 0
        self._fit = self._fit_model()
        if self._ceiling is not None:
            predicted = self._predict(self._ceiling)
            if predicted is not None and predicted < self.target_s / OVERRUN_FACTOR:
                self._ceiling = None  # the model now says it fits with room: lights got cheaper
        self._k = self._decide(k, t)

    def _follow_change(self, k: int, t: float) -> None:
        """When an interval misses the prediction by more than ``CHANGE`` (the scene, the
        resolution or the machine's load changed), forget the samples of the old times and
        pivot the remembered line on its overhead through this one: a lit frame gives the new
        cost, a frame without lights the new overhead."""
        if self._prior is None:
            return  # no informed model yet: its first, high-side guesses are meant to be wrong
        predicted = self._predict(k)
        if predicted is None or abs(t - predicted) <= CHANGE * predicted:
            return
        self._samples.clear()
        a0 = self._fit[0]
        if k == 0:
            self._prior = (t, self._prior[1])
        elif t > a0:
            self._prior = (a0, (t - a0) / k)
        else:  # faster than the overhead alone was: say so on the high side of the cost
            self._prior = (0.0, t / k)

    def _fit_model(self) -> tuple[float, float | None]:
        """(overhead, cost) from the weighted samples and the remembered line; remembers the
        new line when the samples spread over two or more K."""
        ks = np.array([s[0] for s in self._samples], dtype=np.float64)
        ts = np.array([s[1] for s in self._samples], dtype=np.float64)
        w = self.memory ** np.arange(len(ks) - 1, -1, -1, dtype=np.float64)
        spread = _weighted_var(ks, w) > 1e-6
        if self._prior is not None:
            a0, b0 = self._prior
            kref = float(max(self._k, 1))
            ks = np.append(ks, [0.0, kref])
            ts = np.append(ts, [a0, a0 + b0 * kref])
            w = np.append(w, [PRIOR_WEIGHT, PRIOR_WEIGHT])
        if self._prior is None and not spread:
            zero = ks == 0
            overhead = float(np.average(ts[zero], weights=w[zero])) if zero.any() else 0.0
            if zero.all():
                return overhead, None
            lit = ~zero
            k_mean = float(np.average(ks[lit], weights=w[lit]))
            t_mean = float(np.average(ts[lit], weights=w[lit]))
            return overhead, max(t_mean - overhead, 0.0) / k_mean
        k_mean, t_mean = np.average(ks, weights=w), np.average(ts, weights=w)
        var = _weighted_var(ks, w)
        b = float(np.average((ks - k_mean) * (ts - t_mean), weights=w) / var)
        if b <= 1e-9 * self.budget_s:
            # Frames with more lights were not slower: the intervals do not show the lights'
            # cost (a paced runtime, or the overhead changed under the lights). Keep the
            # remembered cost through the samples' mean, or say the cost is unknown.
            if self._prior is None:
                return max(float(t_mean), 0.0), None
            b = self._prior[1]
            return max(float(t_mean - b * k_mean), 0.0), b
        a = max(float(t_mean - b * k_mean), 0.0)
        if spread:
            self._prior = (a, b)
        return a, b

    def _predict(self, k: int) -> float | None:
        if self._fit is None:
            return None
        a, b = self._fit
        if b is None:
            return a if k == 0 else None
        return a + b * k

    def _decide(self, k_drawn: int, t: float) -> int:
        k = self._k
        a, b = self._fit
        target = self.target_s
        cap = self._ceiling - 1 if self._ceiling is not None else self.k_max
        if b is None:  # the intervals have not shown what a light costs
            if k_drawn == 0:
                return k  # nothing drawn: nothing learnt
            if t <= target:
                return max(k, min(2 * k, cap, self.k_max))  # it fits: try more
            return max(1, min(k, math.floor(k * target / t)))  # it does not: scale down
        k_fit = min(max(math.floor((target - a) / b), 1), self.k_max)
        if self._prior is None and k_fit <= k and k_drawn == k and t <= target:
            k_fit = min(k + 1, self.k_max)  # probe: the first cost estimate is on the high side
        if k_fit <= k:
            return k_fit  # drop at once
        return max(k, min(k_fit, 2 * k, cap))


def _weighted_var(x: np.ndarray, w: np.ndarray) -> float:
    mean = np.average(x, weights=w)
    return float(np.average((x - mean) ** 2, weights=w))


#: What a headset's eye may change and still count as "still" (``view_moved``'s tolerance for
#: the VR preview and the bridge): about 1 mm or 0.06°. A tracked head is never exactly still
#: (sub-millimetre tracking noise, poses predicted anew every frame); at 1e-4 it would restart
#: every frame and never get past K lights.
HEAD_STILL_TOLERANCE = 1e-3


def view_moved(a: np.ndarray | None, b: np.ndarray | None, tolerance: float = 1e-4) -> bool:
    """Whether two (4, 4) clip_from_world matrices show different views: True when either is
    None or some entry differs by more than ``tolerance`` times the matrix's scale.

    The scale is the largest entry of the first three columns of either matrix (the
    projection's own scale: rotation times projection, independent of where the world origin
    lies), so the rule reads "the view turned by more than about ``tolerance`` radians or moved
    by more than about ``tolerance`` scene units": the translation column changes by the
    projection times the eye's displacement however far the origin is.
    """
    if a is None or b is None:
        return True
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.shape != (4, 4) or b.shape != (4, 4):
        raise ValueError(f"need two (4, 4) matrices, got {a.shape} and {b.shape}")
    scale = max(float(np.abs(a[:, :3]).max()), float(np.abs(b[:, :3]).max()))
    if not np.all(np.isfinite(a)) or not np.all(np.isfinite(b)):
        return True
    return float(np.abs(a - b).max()) > tolerance * scale

"""Adaptive sampling of the Sampled final render: pixels whose noise has fallen below a threshold
stop taking samples (Cycles' Noise Threshold, its scheme and its defaults).

Besides the sum of a pixel's samples the kernel keeps the sum of half of them (Cycles' "class
A" samples, kernels/render_direct.cl ``in_half``); the difference between the two means is an
estimate of the pixel's noise. The error of a pixel (Dammertz et al. 2010, "A hierarchical
automatic stopping condition for Monte Carlo global illumination", §2.1, as Cycles computes it):

    error = (|I_r − A_r| + |I_g − A_g| + |I_b − A_b|) / (1e-4 + n(I_r + I_g + I_b))

with I the mean of all samples, A the mean of the half, n(s) = sqrt(s) below 1 and s above (so
over-exposed pixels, which no display shows finely, stop sooner). A pixel converges when its
error is below the threshold itself, as in Cycles' kernel (film_adaptive_sampling_convergence_
check: ``error < threshold``, the Noise Threshold passed through unscaled), so the same
threshold means the same here. (Until 2026-12-05 this accepted 5 × the threshold: pixels then
stopped at 2 % relative error on the Lambertian sphere whatever the samples, where Cycles'
went on to 1.3 %; docs/accuracy.md, "Adaptive sampling".)
An unconverged pixel keeps its 3 × 3 neighbours sampling (Cycles' two box-filter passes): a
lone noisy pixel does not leave a stopped ring around itself.

Checks happen every ``ADAPTIVE_STEP`` samples (Cycles' 16) once a pixel has at least the
minimum samples: Cycles' automatic rule ceil(16 / threshold^0.3) (0.1 → 32, 0.01 → 64, 0.001 →
128) capped at a quarter of the pixel's samples, since this renderer renders far fewer samples
than Cycles (64 by default, Cycles 4096) and would otherwise never check; at least 4.

Pure numpy, no device: cl/renderer.py runs it between the passes of render/launch.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

ADAPTIVE_STEP = 16  # samples between convergence checks (Cycles' adaptive_step)
LEAST_MIN_SAMPLES = 4  # Cycles' floor under the minimum samples


def min_samples(threshold: float, samples: int) -> int:
    """The samples every pixel takes before its first check: Cycles' automatic minimum for
    ``threshold``, at most a quarter of ``samples``, at least 4."""
    cycles = math.ceil(16.0 / threshold**0.3)
    return max(LEAST_MIN_SAMPLES, min(cycles, samples // 4))


@dataclass(frozen=True)
class AdaptiveSampling:
    """The schedule and the stopping rule of one render of ``samples`` samples per pixel at
    Noise Threshold ``threshold`` (> 0)."""

    threshold: float
    samples: int

    @classmethod
    def for_render(cls, threshold: float, samples: int) -> AdaptiveSampling | None:
        """The schedule, or None where no pixel could stop: a threshold of 0 (off) or too few
        samples for a check before the last."""
        plan = cls(float(threshold), int(samples))
        if threshold <= 0.0 or plan.next_check(0) is None:
            return None
        return plan

    @property
    def min_samples(self) -> int:
        return min_samples(self.threshold, self.samples)

    def next_check(self, done: int) -> int | None:
        """The sample count of the first check after ``done`` samples: a multiple of the step,
        at least the minimum samples, below the render's samples (a check after the last sample
        would save nothing); None when there is none."""
        at = max(self.min_samples, done + 1)
        at = -(-at // ADAPTIVE_STEP) * ADAPTIVE_STEP
        return at if at < self.samples else None

    def checks_at(self, done: int) -> bool:
        """Whether convergence is checked once every active pixel has ``done`` samples."""
        return done > 0 and self.next_check(done - 1) == done

    def still_active(
        self,
        active: np.ndarray,
        mean: np.ndarray,
        half_mean: np.ndarray,
        in_half: np.ndarray,
        count: np.ndarray,
    ) -> np.ndarray:
        """(h, w) bool: the pixels that keep sampling after a check. ``active``: (h, w) bool,
        those sampling until now; ``mean``, ``half_mean``: (h, w, 3) float32, the means of all
        samples and of the half; ``in_half``, ``count``: (h, w) samples in the half and in all.
        A stopped pixel stays stopped; a pixel whose half holds none or all of its samples
        cannot be judged and goes on (a large Samples per Camera Ray: few groups so far)."""
        judged = (in_half > 0) & (in_half < count)
        calm = judged & (pixel_error(mean, half_mean) < self.threshold)
        return active & dilate(active & ~calm)


def pixel_error(mean: np.ndarray, half_mean: np.ndarray) -> np.ndarray:
    """(h, w) float: Cycles' per-pixel error of (h, w, 3) means of all samples and of half of
    them (the module's docstring has the formula)."""
    mean = np.asarray(mean, np.float32)
    difference = np.abs(mean - np.asarray(half_mean, np.float32)).sum(axis=-1)
    intensity = np.maximum(mean.sum(axis=-1), 0.0)
    normalise = np.where(intensity < 1.0, np.sqrt(intensity), intensity)
    return difference / (np.float32(1e-4) + normalise)


def dilate(mask: np.ndarray) -> np.ndarray:
    """(h, w) bool: ``mask`` grown by one pixel in every direction (3 × 3), as Cycles' box
    filter passes over rows then columns."""
    grown = mask.copy()
    grown[:, 1:] |= mask[:, :-1]
    grown[:, :-1] |= mask[:, 1:]
    rows = grown.copy()
    grown[1:] |= rows[:-1]
    grown[:-1] |= rows[1:]
    return grown

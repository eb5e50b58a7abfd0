"""Angular sampling grids for tabulated BTFs and their interpolation over the hemisphere.

A ring grid holds, for each polar angle θ_r, n_r azimuths φ = k·360/n_r. UBO2003 measured
81 directions on rings θ = 0, 15, …, 75° with 1, 6, 12, 18, 20, 24 azimuths.

Interpolation ("ring-bilinear"): linear in θ between the two rings that bracket the query, and
within each ring linear in φ between the two neighbouring samples (wrapping). At most four
samples get weight; the weights are non-negative, sum to 1 and vary continuously with the
direction (also through the pole, whose single sample's weight tends to 1 there).

Beyond the last ring nothing was measured: the query is clamped onto the last ring (constant
in θ). For light directions the dense codec additionally fades by cos θ / cos θ_last, which
keeps "value = BRDF × cos θi" continuous and reaching 0 at the horizon (core/codecs/dense.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .angles import directions_from_angles_deg


@dataclass(frozen=True)
class RingGrid:
    theta_deg: tuple[float, ...]
    counts: tuple[int, ...]

    def __post_init__(self) -> None:
        if len(self.theta_deg) != len(self.counts) or not self.counts:
            raise ValueError("ring grid: theta_deg and counts must be non-empty and equally long")
        if any(b <= a for a, b in zip(self.theta_deg, self.theta_deg[1:], strict=False)):
            raise ValueError("ring grid: ring angles must increase")
        if min(self.counts) < 1 or self.theta_deg[0] < 0 or self.theta_deg[-1] > 90:
            raise ValueError("ring grid: counts ≥ 1 and angles in [0, 90] required")

    @property
    def size(self) -> int:
        return int(sum(self.counts))

    @property
    def theta_max_deg(self) -> float:
        return self.theta_deg[-1]

    def angles_deg(self) -> tuple[np.ndarray, np.ndarray]:
        """(size,) θ and φ of every sample, ring by ring."""
        theta = np.concatenate(
            [np.full(n, t) for t, n in zip(self.theta_deg, self.counts, strict=True)]
        )
        phi = np.concatenate([np.arange(n) * (360.0 / n) for n in self.counts])
        return theta, phi

    def directions(self) -> np.ndarray:
        return directions_from_angles_deg(*self.angles_deg())

    def ring_pair(self, theta_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The θ rings bracketing each of M angles (clamped to the measured range): r0, r1
        (M,) int64 and the weight of r1 (M,) float64 — the ring step of every ring-grid
        interpolation (here, and svd.ring_weights' uneven azimuths)."""
        rings = np.asarray(self.theta_deg)
        theta = np.clip(theta_deg, rings[0], rings[-1])
        if len(rings) == 1:
            r0 = np.zeros(len(theta), dtype=np.int64)
            wt = np.zeros(len(theta))
        else:
            r0 = np.clip(np.searchsorted(rings, theta, side="right") - 1, 0, len(rings) - 2)
            wt = (theta - rings[r0]) / (rings[r0 + 1] - rings[r0])
        return r0, np.minimum(r0 + 1, len(rings) - 1), wt

    def weights(self, theta_deg: np.ndarray, phi_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Interpolation for M directions: indices (M, 4) int64 and weights (M, 4) float64."""
        counts = np.asarray(self.counts)
        offsets = np.concatenate([[0], np.cumsum(counts)[:-1]])
        r0, r1, wt = self.ring_pair(theta_deg)
        idx = np.empty((len(wt), 4), dtype=np.int64)
        w = np.empty((len(wt), 4))
        for slot, ring, ring_w in ((0, r0, 1.0 - wt), (2, r1, wt)):
            n = counts[ring]
            pos = np.mod(phi_deg, 360.0) / (360.0 / n)
            k0 = np.floor(pos).astype(np.int64) % n
            wp = pos - np.floor(pos)
            idx[:, slot] = offsets[ring] + k0
            idx[:, slot + 1] = offsets[ring] + (k0 + 1) % n
            w[:, slot] = ring_w * (1.0 - wp)
            w[:, slot + 1] = ring_w * wp
        return idx, w


UBO2003 = RingGrid((0.0, 15.0, 30.0, 45.0, 60.0, 75.0), (1, 6, 12, 18, 20, 24))


def uniform_ring_grid(step_deg: float, theta_max_deg: float = 75.0) -> RingGrid:
    """Rings every ``step_deg`` up to ``theta_max_deg``; azimuth spacing ≈ the polar spacing
    on the sphere (n_r = round(360·sin θ_r / step)), one sample at the pole."""
    rings = np.arange(0.0, theta_max_deg + 1e-9, step_deg)
    counts = [
        1 if t == 0 else max(3, round(360.0 * np.sin(np.radians(t)) / step_deg)) for t in rings
    ]
    return RingGrid(tuple(float(t) for t in rings), tuple(int(c) for c in counts))

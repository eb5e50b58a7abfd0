"""Launch planning for the final render: how many rows and samples each kernel launch covers.

A pixel's cost varies by orders of magnitude (lights, samples, bounces, sky vs geometry), so
launches are sized by measured cost: the first launch is small and measures the seconds per
pixel-sample; later ones aim at LAUNCH_SECONDS each, so progress is reported and a cancel
answered between launches at any sample count. Samples go in passes over the whole image of
about PASS_SECONDS each (the Sampled mode's preview cadence); device memory holds one band of at
most BAND_PIXELS pixels.

Pure planning, no device and no clock: the caller runs each ``Launch`` the plan yields, times
it and reports the seconds with ``record`` before asking for the next one.

Fixed split (``fixed=True``, or ``BTF_FIXED_LAUNCHES=1`` in the environment): launches of
FIXED_LAUNCH_PIXELS pixels' rows × FIXED_LAUNCH_SAMPLES samples whatever the timings, so a frame
is bit-identical between runs and machines with the same device (farms that diff frames). The
measured split is not: which samples share a launch changes the float rounding of the sums.

Adaptive sampling (render/adaptive.py): passes end at the sample counts where convergence is
checked (``next_check``), the caller tells the plan after a check how many pixels of each row
are still active (``set_active_rows``), and later passes launch only bands from a row that
has one to the last that has one; ``done`` counts the work of the active pixels, so progress
follows the work actually left.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

BAND_PIXELS = 1 << 17  # most pixels per kernel launch: bounds device memory
FIRST_LAUNCH_PIXELS = 1 << 14  # the first launch measures the cost per pixel
LAUNCH_SECONDS = 0.1  # target per launch: cancel answers within a few times this
PASS_SECONDS = 2.0  # target per progressive pass of the Sampled mode (preview cadence)
FIXED_LAUNCH_PIXELS = 1 << 14  # fixed split: rows per launch cover about this many pixels
FIXED_LAUNCH_SAMPLES = 4  # fixed split: samples per launch
FIXED_ENV = "BTF_FIXED_LAUNCHES"  # "1": every plan made without ``fixed`` given is fixed


def fixed_by_default() -> bool:
    """Whether the environment asks for the fixed split (BTF_FIXED_LAUNCHES=1)."""
    return os.environ.get(FIXED_ENV, "").strip().lower() in ("1", "true", "yes", "on")


@dataclass(frozen=True)
class Launch:
    """Rows [row0, row0 + rows) for samples [first_sample, first_sample + samples).

    done: the fraction of all work finished once this launch is; ends_pass: the last launch of
    a pass over the image; last: the last launch of the whole render (with adaptive sampling a
    pass may also end the render when every pixel has converged); pixels: the active pixels in
    these rows (all of them unless adaptive sampling stopped some)."""

    row0: int
    rows: int
    first_sample: int
    samples: int
    done: float
    ends_pass: bool
    last: bool
    pixels: int = 0


class LaunchPlan:
    """Launches covering ``height`` rows of ``width`` pixels × ``samples`` samples exactly once.

    The limits default to this module's constants as they are when the plan is made (tests and
    benchmarks may change them)."""

    def __init__(
        self,
        width: int,
        height: int,
        samples: int = 1,
        *,
        band_pixels: int | None = None,
        first_launch_pixels: int | None = None,
        launch_seconds: float | None = None,
        pass_seconds: float | None = None,
        fixed: bool | None = None,
        next_check: Callable[[int], int | None] | None = None,
    ):
        self.width, self.height, self.samples = width, height, samples
        #: Adaptive sampling: the sample count of the first convergence check after a given
        #: count (None: no more checks); passes end there. None: no adaptive sampling.
        self.next_check = next_check
        self._active = np.full(height, width, np.int64)  # active pixels per row
        self._active_after = self._suffix(self._active)
        band_pixels = BAND_PIXELS if band_pixels is None else band_pixels
        first_pixels = FIRST_LAUNCH_PIXELS if first_launch_pixels is None else first_launch_pixels
        self.launch_seconds = LAUNCH_SECONDS if launch_seconds is None else launch_seconds
        self.pass_seconds = PASS_SECONDS if pass_seconds is None else pass_seconds
        #: Most rows in one launch: the device buffers hold this many rows of passes.
        self.max_rows = max(1, min(height, band_pixels // width))
        self.cost: float | None = None  # seconds per pixel-sample, measured (decaying maximum)
        self._last_work = 0  # rows × samples of the last launch
        self._rows = max(1, min(self.max_rows, first_pixels // width))
        #: Fixed split: the same launches every run (None: as BTF_FIXED_LAUNCHES says).
        self.fixed = fixed_by_default() if fixed is None else fixed
        if self.fixed:
            self._rows = max(1, min(self.max_rows, FIXED_LAUNCH_PIXELS // max(width, 1)))

    @staticmethod
    def _suffix(active: np.ndarray) -> np.ndarray:
        """(h + 1,) active pixels in rows [r, h) for every r."""
        return np.concatenate([np.cumsum(active[::-1])[::-1], [0]])

    def set_active_rows(self, pixels_per_row: np.ndarray) -> None:
        """After a convergence check: (h,) how many pixels of each row still take samples. The
        passes after it launch only rows with at least one; call it between passes."""
        self._active = np.asarray(pixels_per_row, np.int64)
        self._active_after = self._suffix(self._active)

    def record(self, launch: Launch, seconds: float) -> None:
        """The measured duration of ``launch``: sizes the launches after it."""
        # The cost of the active pixels: inactive ones return at once (kernels/render_direct.cl).
        pixels = launch.pixels or launch.rows * self.width
        measured = max(seconds, 1e-6) / (pixels * launch.samples)
        # A decaying maximum: a slow launch counts at once, a fast one lowers the estimate
        # at most by half, so one cheap band cannot make the next launch far too long.
        self.cost = measured if self.cost is None else max(measured, 0.5 * self.cost)
        self._last_work = launch.rows * launch.samples

    def _samples_per_launch(self, first: int) -> int:
        # A pass ends at the next convergence check (Cycles' align_samples).
        check = self.next_check(first) if self.next_check is not None else None
        last = self.samples if check is None else min(check, self.samples)
        if self.fixed:
            return min(FIXED_LAUNCH_SAMPLES, last - first)
        if self.cost is None:
            return 1
        w, h = self.width, self.height
        per_pass = self.pass_seconds / (self.cost * w * h)
        per_row = self.launch_seconds / (self.cost * w)
        return int(np.clip(min(per_pass, per_row), 1, last - first))

    def _next_active_row(self, row: int) -> int:
        """The first row at or after ``row`` with an active pixel; ``height`` if none."""
        ahead = np.flatnonzero(self._active[row:])
        return row + int(ahead[0]) if len(ahead) else self.height

    def _active_run(self, row0: int, limit: int) -> int:
        """How many rows from ``row0`` (active) on, at most ``limit``, up to the last with an
        active pixel. Idle rows between active ones go along: their pixels return at once,
        and a launch costs more than they do (every launch traces each active pixel's camera
        ray and its sharp-lobe test again, and waits for the device): cutting a pass at every
        idle row made the adaptive demo 253 launches for 1024 samples, 67 this way (its F12
        1.84 s -> 1.72 s)."""
        active = np.flatnonzero(self._active[row0 : row0 + limit])
        return int(active[-1]) + 1 if len(active) else 1

    def _rows_for(self, count: int) -> int:
        if self.cost is not None and not self.fixed:
            # Costs differ across the image (sky rows are cheap): grow a launch at most 2× over
            # the last one, so a cheap region cannot talk it into a huge one.
            limit = min(self.max_rows, max(1, 2 * self._last_work // count))
            rows = self.launch_seconds / (self.cost * self.width * count)
            self._rows = int(np.clip(rows, 1, limit))
        return self._rows

    def __iter__(self) -> Iterator[Launch]:
        h, samples = self.height, self.samples
        first = 0
        finished = 0  # pixel-samples launched so far
        while first < samples and self._active_after[0] > 0:
            count = self._samples_per_launch(first)
            row0 = self._next_active_row(0)
            while row0 < h:
                band = self._active_run(row0, self._rows_for(count))
                end = row0 + band
                pixels = int(self._active_after[row0] - self._active_after[end])
                finished += pixels * count
                # Left: this pass's active rows below, then every active pixel's later samples.
                left = int(self._active_after[end]) * count
                left += int(self._active_after[0]) * (samples - first - count)
                after = self._next_active_row(end)
                yield Launch(
                    row0=row0,
                    rows=band,
                    first_sample=first,
                    samples=count,
                    done=finished / (finished + left),
                    ends_pass=after == h,
                    last=after == h and first + count >= samples,
                    pixels=pixels,
                )
                row0 = after
            first += count

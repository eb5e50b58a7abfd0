"""The light bake's knobs in the accuracy report: per bake setting, the baked drawer's error
against the report's F12 reference, the bake's time and the GPU memory its playback takes.
bpy- and device-free: baking and playing back is a callable the caller passes
(blender/accuracy/run.py ``BakeRunner`` binds it to cl/bake.py).

The sweep goes one knob at a time from the scene's own bake settings (``scene.btf_bake``), as
the render ladder does: point spacing (coarser), view directions (fewer and more), samples
(fewer). No finer spacing than the scene's own: each halving costs four times the bake. The
values are stored as float32 (12 bytes a point and direction); there is no compression knob
yet.

Error: relative RMSE (render/accuracy/ladder.py's measure) over the pixels where a baked
object is seen, the World's pixels left out (they are the same image whatever the bake);
the baked image is the drawer's converged one (the film's subpixels, what a still head sees
after 16 frames).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

#: Knob → values tried beside the scene's own (scaled for spacing).
SPACING_FACTORS = (2.0, 4.0)
VIEW_BINS = (3, 5, 7)
SAMPLES = (16, 32, 64)


@dataclass(frozen=True)
class BakeRung:
    """One bake setting; ``knob``: the one knob changed from the scene's own ("scene's own"
    for the scene's settings)."""

    spacing: float
    view_bins: int
    samples: int
    knob: str


@dataclass(frozen=True)
class BakeResult:
    """What the caller's bake-and-play gives back: the converged baked image (h, w, ≥ 3), the
    mask of pixels where a baked object is seen, the bake's seconds, the bytes playback
    uploads and how many objects were baked."""

    image: np.ndarray
    mask: np.ndarray
    seconds: float
    gpu_bytes: int
    objects: int


@dataclass(frozen=True)
class BakePoint:
    rung: BakeRung
    seconds: float
    gpu_bytes: int
    objects: int
    rmse: float


#: (rung, progress in [0, 1] → go on?) → the result, or None where progress said stop.
BakeFn = Callable[[BakeRung, Callable[[float], bool]], BakeResult | None]


def bake_rungs(spacing: float, view_bins: int, samples: int) -> list[BakeRung]:
    """The scene's own setting first, then one knob at a time, cheaper first."""
    own = BakeRung(spacing, view_bins, samples, "scene's own")
    rungs = [own]
    for factor in SPACING_FACTORS:
        rungs.append(BakeRung(spacing * factor, view_bins, samples, "spacing"))
    for bins in VIEW_BINS:
        if bins != view_bins:
            rungs.append(BakeRung(spacing, bins, samples, "view directions"))
    for count in SAMPLES:
        if count < samples:
            rungs.append(BakeRung(spacing, view_bins, count, "samples"))
    return rungs


def masked_rmse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    """Relative RMSE over the pixels of ``mask`` (NaN where it holds none)."""
    if not np.any(mask):
        return float("nan")
    d = image[..., :3][mask].astype(np.float64) - reference[..., :3][mask]
    scale = np.sqrt(np.mean(np.square(reference[..., :3][mask], dtype=np.float64)))
    return float(np.sqrt(np.mean(d**2)) / scale) if scale > 0 else float("nan")


def sweep(
    rungs: Sequence[BakeRung],
    bake: BakeFn,
    reference: np.ndarray,
    on_progress: Callable[[float, str], None] | None = None,
    cancelled: Callable[[], bool] = lambda: False,
) -> list[BakePoint]:
    """Bake and play back every rung, scoring each against ``reference``; a cancel keeps the
    rungs finished before it."""
    points: list[BakePoint] = []
    for n, rung in enumerate(rungs):
        text = f"light bake: {rung.knob} (spacing {rung.spacing:g}, {rung.view_bins}² views, "
        text += f"{rung.samples} samples)"

        def progress(fraction: float, n=n, text=text) -> bool:
            if on_progress is not None:
                on_progress((n + min(max(fraction, 0.0), 1.0)) / len(rungs), text)
            return not cancelled()

        if not progress(0.0):
            break
        result = bake(rung, progress)
        if result is None or cancelled():
            break
        error = masked_rmse(result.image, reference, result.mask)
        points.append(BakePoint(rung, result.seconds, result.gpu_bytes, result.objects, error))
    return points


def to_json(points: Sequence[BakePoint]) -> list[dict]:
    return [
        {
            "knob": p.rung.knob,
            "spacing": p.rung.spacing,
            "view_bins": p.rung.view_bins,
            "samples": p.rung.samples,
            "seconds": round(p.seconds, 3),
            "gpu_mib": round(p.gpu_bytes / 2**20, 3),
            "objects": p.objects,
            "rmse": round(p.rmse, 6) if np.isfinite(p.rmse) else None,
        }
        for p in points
    ]


def row_words(row: dict) -> str:
    """One row in words, for the Quality vs Time panel."""
    error = "n/a" if row["rmse"] is None else f"{row['rmse']:.1%} error"
    return (
        f"Bake {row['spacing']:g} apart, {row['view_bins']}×{row['view_bins']} views, "
        f"{row['samples']} samples: {error}, {row['seconds']:.0f} s, {row['gpu_mib']:.1f} MiB"
    )


def markdown(rows: Sequence[dict], size: tuple[int, int]) -> list[str]:
    """The report's section for ``to_json``'s rows (none: no section)."""
    if not rows:
        return []
    w, h = size
    lines = [
        "## Light bake for VR: error vs bake time and GPU memory",
        "",
        f"The baked drawer's converged image against the reference at {w}x{h}, over the "
        "pixels where a baked object is seen. Bake seconds include the analysis and the grid; "
        "GPU memory is what playback uploads (values stored as float32, no compression yet).",
        "",
        "| knob | spacing | view directions | samples | bake s | GPU MiB | objects baked "
        "| relative RMSE |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['knob']} | {r['spacing']:g} | {r['view_bins']}×{r['view_bins']} | "
            f"{r['samples']} | {r['seconds']} | {r['gpu_mib']} | {r['objects']} | "
            f"{'n/a' if r['rmse'] is None else round(r['rmse'], 4)} |"
        )
    lines.append("")
    return lines

"""The accuracy report's files from an ``accuracy.Estimate``: ``report.json`` (machine-readable,
rewritten after every rung, atomically), ``report.md`` and ``report.html`` with the plots
(``error_vs_time.png``, ``ssim_vs_time.png``), error heat maps (``heat_*.png``) and the
reference image (``reference.png``). bpy-free."""

from __future__ import annotations

import html
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from ...core.fileio import atomic_write
from ...core.formats.imageio import srgb8_from_linear, write_png
from .bake_sweep import markdown as bake_markdown
from .ladder import (
    Estimate,
    Role,
    _class_text,
    all_knobs,
    cost_class,
    describe_rung,
    describe_words,
    error_map,
    pareto_front,
    quality_words,
    recommend,
    reference_noise,
    settings_json,
    ssim_map,
)
from .plot import Plot, Series, heat_map, render_plot

JSON_NAME = "report.json"
METRICS = {"rmse": "relative RMSE", "ssim_loss": "1 - SSIM"}


def _num(value: float) -> float | None:
    return round(float(value), 6) if math.isfinite(value) else None


def unit_of(key: tuple, estimate: Estimate) -> str:
    """The unit of work of a cost class's rate ("pixel·lights_total", "pixel·samples")."""
    for p in estimate.points:
        if cost_class(p.rung) == key:
            names = [
                k.name for k in all_knobs() if k.role is Role.WORK and k.applies(p.rung.settings)
            ]
            return "·".join(["pixel", *names])
    return "pixel"


def to_json(
    estimate: Estimate, budget: float | None = None, target: float | None = None
) -> dict[str, Any]:
    """Everything the report shows, as plain JSON values."""
    points = estimate.points
    front = set(pareto_front(points)) if points else set()
    rec = recommend(points, budget, target) if points else None
    out: dict[str, Any] = {
        "scene": estimate.scene,
        "device": estimate.device,
        "preview_size": list(estimate.preview_size),
        "full_size": list(estimate.full_size),
        "budget_seconds": budget,
        "target_rmse": target,
        "interrupted": estimate.interrupted,
        "rungs_done": len(points),
        "rungs_total": estimate.rungs_total,
        "base_settings": settings_json(estimate.base),
        "reference": {
            "settings": settings_json(estimate.reference),
            "seconds": _num(estimate.reference_seconds),
            "size": list(estimate.preview_size),
            "noise_rmse": _num(noise) if (noise := reference_noise(estimate)) else None,
        },
        "setup_seconds": _num(estimate.setup_seconds),
        "points": [
            {
                "series": p.rung.series,
                "sweep": p.rung.sweep,
                "knobs": p.rung.knob_values(),
                "settings": settings_json(p.rung.settings),
                "extra": dict(p.rung.extra),
                "seconds": _num(p.seconds),
                "predicted_seconds": _num(p.predicted_seconds),
                "rmse": _num(p.rmse),
                "ssim_loss": _num(p.ssim_loss),
                "pareto": i in front,
                "seeds": p.seeds,
            }
            for i, p in enumerate(points)
        ],
        "time_model": None,
        "recommendation": None,
        "bake": list(estimate.bake),
    }
    if estimate.model is not None:
        out["time_model"] = {
            "setup_seconds": _num(estimate.model.setup_seconds),
            "max_residual": _num(estimate.model.residual),
            "classes": [
                {
                    "class": dict(key),
                    "overhead_seconds": _num(overhead),
                    "ns_per_unit": _num(rate * 1e9),
                    "unit": unit_of(key, estimate),
                }
                for key, (overhead, rate) in estimate.model.classes.items()
            ],
        }
    if rec is not None:
        p = points[rec.index]
        out["recommendation"] = {
            "index": rec.index,
            "reason": rec.reason,
            "met": rec.met,
            "describe": describe_rung(p.rung),
            "words": recommendation_words(p, estimate.full_size),
            "reason_words": "" if rec.met else missed_words(p, budget, target),
            "knobs": p.rung.knob_values(),
            "settings": settings_json(p.rung.settings),
            "rmse": _num(p.rmse),
            "ssim_loss": _num(p.ssim_loss),
            "predicted_seconds": _num(p.predicted_seconds),
            "seeds": p.seeds,
            "rmse_upper": _num(p.rmse_upper),
        }
    return out


def recommendation_words(point, full_size: tuple[int, int]) -> str:
    """ "64 samples: noise barely visible, 35 s at full size (320×240)": what the panel says."""
    seconds = point.predicted_seconds
    time = f"{seconds:.0f} s" if seconds >= 10 else f"{seconds:.1f} s"
    return (
        f"{describe_words(point.rung)}: {quality_words(point.rmse, point.rung.settings.sampled)}"
        f", {time} at full size ({full_size[0]}×{full_size[1]})"
    )


def missed_words(point, budget: float | None, target: float | None) -> str:
    """Why the recommendation misses the request, and what would meet a missed error target:
    a Sampled image's noise falls as 1/√samples, so n·(error/target)² samples reach it (the
    time grows with the samples; an extrapolation, stated as one)."""
    if target is not None and point.rmse > target:
        settings = point.rung.settings
        if not settings.sampled:
            return (
                f"No setting measured reaches {target:.0%} error: use Sampled, or more virtual "
                "lights (the Full estimate measures them)"
            )
        n = math.ceil(settings.samples * (point.rmse / target) ** 2)
        seconds = point.predicted_seconds * n / settings.samples
        return (
            f"No setting measured reaches {target:.0%} error: about {n} samples would "
            f"(noise falls as 1/√samples), ≈ {seconds:.0f} s at full size (extrapolated)"
        )
    if budget is not None:
        return f"Nothing measured fits {budget:g} s: this is the fastest"
    return ""


def write_json(folder: Path, data: dict[str, Any]) -> Path:
    text = json.dumps(data, indent=1, allow_nan=False)
    return atomic_write(Path(folder) / JSON_NAME, lambda fh: fh.write(text.encode()))


def error_plot(
    data: dict[str, Any],
    metric: str = "rmse",
    size: tuple[int, int] = (640, 420),
    scale: int = 1,
) -> np.ndarray:
    """Error (``metric``) against predicted full-resolution time, log–log, from a report's
    JSON (``to_json``: so the Blender panel redraws it from the stored report): one curve per
    swept knob, the Pareto front in black, the recommendation circled, the budget and target
    as dashed lines. (h, w, 3) uint8."""
    points = data["points"]
    fw, fh = data["full_size"]
    plot = Plot(
        title=f"{METRICS[metric]} vs time at {fw}x{fh}",
        x_label="predicted seconds (full resolution)",
        y_label=METRICS[metric],
        x_log=True,
        y_log=True,
    )
    by_series: dict[str, list[dict]] = {}
    for p in points:
        by_series.setdefault(p["series"], []).append(p)
    for name, members in by_series.items():
        members = sorted(members, key=lambda p: p["predicted_seconds"] or 0.0)
        plot.series.append(Series(name, *_xy(members, metric)))
    front = [points[i] for i in _front(points, metric)]
    if len(front) > 1:
        xs, ys = _xy(front, metric)
        plot.series.append(Series("Pareto front", xs, ys, colour=(0, 0, 0), width=1, marker=0))
    rec = data.get("recommendation")
    if rec is not None and metric == "rmse":
        plot.rings.append((rec["predicted_seconds"] or math.nan, rec["rmse"] or math.nan))
    budget, target = data.get("budget_seconds"), data.get("target_rmse")
    if budget is not None:
        plot.vlines.append((budget, f"budget {budget:g} s"))
    if target is not None and metric == "rmse":
        plot.hlines.append((target, f"target {target:g}"))
    return render_plot(plot, *size, scale=scale)


def _xy(points: list[dict], metric: str) -> tuple[list[float], list[float]]:
    def num(v):
        return math.nan if v is None else float(v)

    return [num(p["predicted_seconds"]) for p in points], [num(p[metric]) for p in points]


def _front(points: list[dict], metric: str) -> list[int]:
    """The Pareto front of JSON points in ``metric`` (the stored flag is for RMSE)."""
    stand_ins = []
    for p in points:
        x, y = p["predicted_seconds"], p[metric]
        stand_ins.append(_Pt(math.inf if x is None else x, math.inf if y is None else y))
    return pareto_front(stand_ins, "error")


class _Pt:
    def __init__(self, seconds: float, error: float):
        self.predicted_seconds, self.error = seconds, error


def write_report(
    folder: Path, estimate: Estimate, budget: float | None = None, target: float | None = None
) -> dict[str, Path]:
    """All files of the report into ``folder``; returns {kind: path}."""
    folder = Path(folder)
    data = to_json(estimate, budget, target)
    written = {"json": write_json(folder, data)}
    if estimate.reference_image is not None:
        written["reference"] = write_png(
            folder / "reference.png", srgb8_from_linear(estimate.reference_image)
        )
    if not estimate.points:
        written["markdown"] = _write_text(folder / "report.md", _markdown(data, {}))
        return written
    for metric, name in (("rmse", "error_vs_time.png"), ("ssim_loss", "ssim_vs_time.png")):
        written[metric] = write_png(folder / name, error_plot(data, metric))
    heat = {}
    rec = data["recommendation"]
    base_index = _base_index(estimate)
    chosen = {"recommended": rec["index"] if rec else None, "scene": base_index}
    vmax = None
    for kind, index in chosen.items():
        if index is None:
            continue
        image = estimate.images[index]
        err = error_map(image, estimate.reference_image)
        vmax = vmax or max(float(np.percentile(err, 99)), 1e-6)  # one scale for both maps
        label = f"{kind}: {describe_rung(estimate.points[index].rung)}"
        path = write_png(folder / f"heat_{kind}.png", heat_map(err, vmax, "rel. error"))
        ssim = 1 - ssim_map(image, estimate.reference_image)
        spath = write_png(folder / f"heat_ssim_{kind}.png", heat_map(ssim, 0.5, "1 - SSIM"))
        heat[kind] = (label, path.name, spath.name)
        written[f"heat_{kind}"] = path
    written["markdown"] = _write_text(folder / "report.md", _markdown(data, heat))
    written["html"] = _write_text(folder / "report.html", _html(_markdown(data, heat)))
    return written


def _base_index(estimate: Estimate) -> int | None:
    for i, p in enumerate(estimate.points):
        if p.rung.settings == estimate.base and not p.rung.extra:
            return i
    return None


def _write_text(path: Path, text: str) -> Path:
    return atomic_write(path, lambda fh: fh.write(text.encode()))


def _s(value) -> str:
    if value is None:
        return "-"
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _markdown(data: dict[str, Any], heat: dict[str, tuple[str, str, str]]) -> str:
    pw, ph = data["preview_size"]
    fw, fh = data["full_size"]
    ref = data["reference"]
    lines = [
        f"# Quality vs time: {data['scene']}",
        "",
        f"Device: {data['device']}. The ladder was rendered at **{pw}x{ph}** (a reduced size, "
        f"so this report stays cheap); times are predicted for the scene's own **{fw}x{fh}** "
        "from the time per pixel·light / pixel·sample measured here (errors do not depend on "
        "the size: every pixel is a point sample with the same noise and bias).",
        "",
        f"Reference: sampled, {ref['settings']['samples']} samples, "
        f"{ref['settings']['max_bounces']} bounces, seed {ref['settings']['seed']} — "
        f"{_s(ref['seconds'])} s at {pw}x{ph}. Setup (export, device, upload): "
        f"{_s(data['setup_seconds'])} s. Its own noise, estimated from the samples sweep: "
        f"relative RMSE {_s(ref['noise_rmse'])} — errors near it are the reference's noise "
        "(raise --reference-samples to resolve them).",
        "",
        "Errors against the reference: **relative RMSE** (linear radiance) and **1 − SSIM** "
        "(structural similarity of the displayed sRGB luminance, Gaussian σ = 1.5 px).",
        "",
    ]
    if data["interrupted"]:
        lines += [
            f"**Interrupted** after {data['rungs_done']} of {data['rungs_total']} settings: "
            "the numbers below are what was done.",
            "",
        ]
    rec = data["recommendation"]
    if rec is not None:
        lines += [
            "## Recommended",
            "",
            f"**{rec['words']}**." + (f" {rec['reason_words']}." if rec["reason_words"] else ""),
            "",
            f"Settings: {rec['describe']} — {rec['reason']}: relative RMSE {_s(rec['rmse'])}, "
            f"1 − SSIM {_s(rec['ssim_loss'])}, predicted {_s(rec['predicted_seconds'])} s "
            f"at {fw}x{fh}" + ("" if rec["met"] else " (the request could not be met)") + ".",
            "",
            f"Upper bound of its relative RMSE (one-sided 90 % over the seeds): "
            f"{_s(rec['rmse_upper'])}. Its errors are pooled over {rec['seeds']} image(s) of "
            "different seeds "
            f"({rec['seeds']} × the preview's pixels): rare bright pixels (fireflies) carry much "
            "of a noisy render's squared error, and one small preview holds fewer of them than "
            "the full-size image will. Errors of the other settings are from one preview each.",
            "",
        ]
    if data["points"]:
        lines += [
            "![relative RMSE vs time](error_vs_time.png)",
            "",
            "![1 - SSIM vs time](ssim_vs_time.png)",
            "",
            "## Every setting measured",
            "",
            f"| curve | settings | s at {pw}x{ph} | predicted s at {fw}x{fh} | relative RMSE "
            "| 1 − SSIM | Pareto |",
            "|---|---|---|---|---|---|---|",
        ]
        for p in data["points"]:
            knobs = ", ".join(f"{k}={v}" for k, v in p["knobs"].items())
            lines.append(
                f"| {p['series']} | {knobs} | {_s(p['seconds'])} | "
                f"{_s(p['predicted_seconds'])} | {_s(p['rmse'])} | {_s(p['ssim_loss'])} | "
                f"{'yes' if p['pareto'] else ''} |"
            )
        lines.append("")
    model = data["time_model"]
    if model:
        lines += [
            "## Time model",
            "",
            f"seconds = setup {_s(model['setup_seconds'])} s + overhead + ns per unit × units. "
            f"The fit's largest residual on the ladder: {100 * model['max_residual']:.0f} % "
            "(the timing noise of this device while it measured: expect full-size times "
            "at least that far from the prediction).",
            "",
            "| cost class | overhead s | ns per unit | unit |",
        ]
        lines.append("|---|---|---|---|")
        for c in model["classes"]:
            key = tuple(c["class"].items())
            lines.append(
                f"| {_class_text(key)} | {_s(c['overhead_seconds'])} | "
                f"{_s(c['ns_per_unit'])} | {c['unit']} |"
            )
        lines.append("")
    lines += bake_markdown(data.get("bake", []), (pw, ph))
    if heat:
        lines += ["## Where the error sits", ""]
        for _kind, (label, rmse_png, ssim_png) in heat.items():
            lines += [f"{label}:", "", f"![{label}]({rmse_png}) ![{label}]({ssim_png})", ""]
        lines += ["Reference:", "", "![reference](reference.png)", ""]
    return "\n".join(lines)


def _html(markdown: str) -> str:
    """The Markdown's own simple forms (headings, paragraphs, images, one table style) as
    HTML: one source of text for both files."""
    out = ["<!doctype html><meta charset='utf-8'><title>Quality vs time</title>", "<body>"]
    rows: list[list[str]] = []

    def flush():
        if rows:
            head, *body = rows
            out.append("<table border=1 cellspacing=0 cellpadding=3>")
            out.append("<tr>" + "".join(f"<th>{c}</th>" for c in head) + "</tr>")
            for r in body:
                out.append("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>")
            out.append("</table>")
            rows.clear()

    for line in markdown.splitlines():
        if line.startswith("|"):
            cells = [html.escape(c.strip()) for c in line.strip("|").split("|")]
            if not all(set(c) <= {"-"} for c in cells):
                rows.append(cells)
            continue
        flush()
        if line.startswith("#"):
            level = len(line) - len(line.lstrip("#"))
            out.append(f"<h{level}>{html.escape(line[level:].strip())}</h{level}>")
        elif line.strip():
            text = html.escape(line)
            text = _images(text)
            text = _bold(text)
            out.append(f"<p>{text}</p>")
    flush()
    out.append("</body>")
    return "\n".join(out)


def _images(text: str) -> str:
    return re.sub(r"!\[([^\]]*)\]\(([^)]+)\)", r"<img alt='\1' src='\2'>", text)


def _bold(text: str) -> str:
    return re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", text)

"""render/accuracy/plot.py (the numpy line-plot raster) and render/accuracy/report.py (the report's
files) on injected results."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from helpers import read_png

from btf_addon.render.accuracy import ladder as acc
from btf_addon.render.accuracy.plot import (
    HEAT_STOPS,
    Plot,
    Series,
    heat_colours,
    heat_map,
    render_plot,
)
from btf_addon.render.accuracy.report import to_json, write_report
from btf_addon.render.settings import RenderSettings


@pytest.fixture(autouse=True)
def core_knobs(monkeypatch):
    """The report is tested on the lights/samples/bounces ladder (its rung counts)."""
    monkeypatch.setattr(acc, "KNOBS", acc.KNOBS[:4])


RED = (230, 0, 0)


def _pixels_of(img, colour):
    ys, xs = np.nonzero(np.all(img == np.array(colour, np.uint8), axis=-1))
    return xs, ys


def test_log_axes_place_points_by_their_logarithm():
    """Markers at x = 2, 20, 200 on a log axis are equally spaced; y = 0.0005 … 0.05
    likewise, and a larger y is higher on the image."""
    plot = Plot(
        series=[Series("", [2, 20, 200], [0.05, 0.005, 0.0005], colour=RED, width=0, marker=2)],
        x_log=True,
        y_log=True,
    )
    img = render_plot(plot, 400, 300)
    assert img.shape == (300, 400, 3) and img.dtype == np.uint8
    xs, ys = _pixels_of(img, RED)
    assert len(xs) == 3 * 25  # three whole 5 × 5 markers (no legend: the series has no label)
    order = np.argsort(xs)
    centres = [(xs[order[i : i + 25]].mean(), ys[order[i : i + 25]].mean()) for i in (0, 25, 50)]
    (x0, y0), (x1, y1), (x2, y2) = centres
    # Equal spacing within a pixel (rounding of each marker's centre).
    assert abs((x1 - x0) - (x2 - x1)) <= 1 and abs((y1 - y0) - (y2 - y1)) <= 1
    assert x0 < x1 < x2 and y0 < y1 < y2  # y falls → lower on the image (larger row)


def test_plot_draws_text_lines_and_skips_what_log_axes_cannot_show():
    plot = Plot(
        series=[
            Series("curve", [1, 2, 4], [1, 0.5, 0.25], colour=RED),
            Series("bad", [0, -1, math.nan], [1, 2, 3]),  # nothing a log axis can show
        ],
        title="title",
        x_label="seconds",
        y_label="error",
        x_log=True,
        y_log=True,
        hlines=[(0.3, "target")],
        vlines=[(3, "budget")],
        rings=[(2, 0.5)],
    )
    img = render_plot(plot, 320, 240)
    xs, _ys = _pixels_of(img, RED)
    assert len(xs) > 100  # a 2-pixel line across most of the width
    dark = np.all(img < 60, axis=-1)
    assert dark[:20].any() and dark[-20:].any() and dark[:, :20].any()  # title, x and y labels
    with pytest.raises(ValueError, match="at least"):
        render_plot(plot, 50, 50)


def test_heat_map_colours_are_monotone_and_clip():
    ramp = heat_colours(np.linspace(0, 2, 50)[None, :], 1.0)[0].astype(float)
    lightness = ramp @ np.array([0.2126, 0.7152, 0.0722])
    assert np.all(np.diff(lightness) >= 0)  # reads in greyscale too
    assert tuple(ramp[0]) == HEAT_STOPS[0][1] and tuple(ramp[-1]) == HEAT_STOPS[-1][1]
    image = heat_map(np.ones((6, 8)), 2.0, "label", min_width=100)
    assert image.shape[1] == 13 * 8  # enlarged by a whole factor to ≥ 100 pixels


def _estimate(rng):
    ref = rng.uniform(0.2, 1.0, (12, 16, 3)).astype(np.float32)
    base = RenderSettings(lights_total=64, samples=16, max_bounces=2)
    est = acc.Estimate(base, (16, 12), (160, 120), acc.reference_settings(base, 64))
    est.reference_image, est.reference_seconds, est.setup_seconds = ref, 0.5, 0.1
    est.scene, est.device = "Scene", "test device"
    rungs = acc.ladder(base)
    est.rungs_total = len(rungs)
    for rung in rungs[:8]:
        s = rung.settings
        scale = 1.0 / (s.samples if s.sampled else s.lights_total)
        image = ref * (1 + scale) + rng.normal(0, 0.01, ref.shape).astype(np.float32)
        est.points.append(
            acc.Point(
                rung,
                1e-6 * acc.work_units(rung, 192),
                acc.relative_rmse(image, ref),
                acc.ssim_loss(image, ref),
            )
        )
        est.images.append(image)
    est.refit()
    return est


def test_report_files_and_json(tmp_path, rng):
    est = _estimate(rng)
    written = write_report(tmp_path, est, budget=20.0, target=0.05)
    data = json.loads((tmp_path / "report.json").read_text())
    assert data == to_json(est, 20.0, 0.05)
    assert data["rungs_done"] == 8 and data["rungs_total"] == 13
    rec = data["recommendation"]
    chosen = est.points[rec["index"]]
    assert rec["predicted_seconds"] <= 20.0 and rec["rmse"] <= 0.05 and rec["met"]
    # The fastest that reaches the target within the budget.
    assert all(
        p.predicted_seconds >= chosen.predicted_seconds
        for p in est.points
        if p.rmse <= 0.05 and p.predicted_seconds <= 20.0
    )
    assert sum(p["pareto"] for p in data["points"]) >= 2
    units = {c["unit"] for c in data["time_model"]["classes"]}
    assert units == {"pixel·lights_total", "pixel·samples"}
    for kind in ("rmse", "ssim_loss", "reference", "heat_recommended", "heat_scene"):
        assert read_png(written[kind]).shape[2] == 3, kind
    md = (tmp_path / "report.md").read_text()
    assert "## Recommended" in md and "error_vs_time.png" in md and "160x120" in md
    page = (tmp_path / "report.html").read_text()
    assert "<table" in page and "<img alt='relative RMSE vs time' src='error_vs_time.png'>" in page


def test_a_report_of_nothing_yet_still_writes(tmp_path):
    base = RenderSettings()
    est = acc.Estimate(base, (8, 6), (80, 60), acc.reference_settings(base))
    est.interrupted = True
    written = write_report(tmp_path, est)
    data = json.loads(written["json"].read_text())
    assert data["interrupted"] and data["points"] == [] and data["recommendation"] is None
    assert "Interrupted" in written["markdown"].read_text()

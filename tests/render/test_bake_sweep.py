"""The light bake's knobs in the accuracy report (render/accuracy/bake_sweep.py), device-free:
the rungs (one knob at a time from the scene's own), the error each is scored with, a cancel
keeping what is finished, and the report's rows."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.render.accuracy import bake_sweep
from btf_addon.render.accuracy.bake_sweep import BakeResult, bake_rungs, markdown, sweep, to_json


def test_rungs_go_one_knob_at_a_time_from_the_scenes_own():
    rungs = bake_rungs(0.05, 5, 64)
    assert rungs[0] == bake_sweep.BakeRung(0.05, 5, 64, "scene's own")
    changed = {(r.knob, r.spacing, r.view_bins, r.samples) for r in rungs[1:]}
    assert changed == {
        ("spacing", 0.1, 5, 64),
        ("spacing", 0.2, 5, 64),
        ("view directions", 0.05, 3, 64),
        ("view directions", 0.05, 7, 64),
        ("samples", 0.05, 5, 16),
        ("samples", 0.05, 5, 32),
    }
    # never finer than the scene's own spacing, never more samples: each costs more bake
    assert all(r.spacing >= 0.05 and r.samples <= 64 for r in rungs)
    assert len(bake_rungs(0.5, 2, 16)) == 1 + 2 + 3  # no fewer samples than 16 to try


def _fake(errors: dict, reference: np.ndarray, mask: np.ndarray, calls: list):
    """A bake-and-play whose image is the reference scaled by 1 + e on the mask (relative RMSE
    exactly e there) and wrong by 100× off it (the World's pixels: must not count)."""

    def bake(rung, progress):
        calls.append(rung)
        for f in (0.0, 0.5, 1.0):
            if not progress(f):
                return None
        image = np.where(mask[..., None], reference * (1 + errors[rung.view_bins]), 100.0)
        return BakeResult(image, mask, 1.5, 3 * 2**20, 2)

    return bake


def test_each_rung_is_scored_over_the_baked_objects_pixels_only():
    rng = np.random.default_rng(3)
    reference = rng.uniform(0.1, 2.0, (12, 16, 3))
    mask = np.zeros((12, 16), bool)
    mask[3:9, 4:12] = True
    rungs = bake_rungs(0.1, 5, 16)
    errors = {3: 0.08, 5: 0.03, 7: 0.02}
    fractions = []
    points = sweep(
        rungs, _fake(errors, reference, mask, []), reference, lambda f, t: fractions.append(f)
    )
    assert [p.rung for p in points] == rungs
    for p in points:
        assert p.rmse == pytest.approx(errors[p.rung.view_bins], rel=1e-12)
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    rows = to_json(points)
    assert rows[0] == {
        "knob": "scene's own",
        "spacing": 0.1,
        "view_bins": 5,
        "samples": 16,
        "seconds": 1.5,
        "gpu_mib": 3.0,
        "objects": 2,
        "rmse": 0.03,
    }
    text = "\n".join(markdown(rows, (16, 12)))
    assert "| scene's own | 0.1 | 5×5 | 16 | 1.5 | 3.0 | 2 | 0.03 |" in text
    assert markdown([], (16, 12)) == []  # no sweep, no section


def test_a_cancel_keeps_the_rungs_finished_before_it():
    reference = np.ones((4, 4, 3))
    mask = np.ones((4, 4), bool)
    rungs = bake_rungs(0.1, 5, 64)
    calls: list = []
    state = {"cancel": False}
    bake = _fake({3: 0.1, 5: 0.1, 7: 0.1}, reference, mask, calls)

    def cancel_on_third(rung, progress):
        if len(calls) == 2:
            state["cancel"] = True  # arrives while the third rung bakes
        return bake(rung, progress)

    points = sweep(rungs, cancel_on_third, reference, cancelled=lambda: state["cancel"])
    assert [p.rung for p in points] == rungs[:2] and len(calls) == 3


def test_an_empty_mask_scores_nan_and_the_report_says_n_a():
    reference = np.ones((4, 4, 3))
    nothing = np.zeros((4, 4), bool)
    (point,) = sweep(
        bake_rungs(0.5, 2, 16)[:1],
        lambda rung, progress: BakeResult(reference, nothing, 0.1, 10, 0),
        reference,
    )
    assert np.isnan(point.rmse) and to_json([point])[0]["rmse"] is None
    assert "| n/a |" in markdown(to_json([point]), (4, 4))[-2]

"""render/accuracy/ladder.py: the knob ladder, error metrics, time model (injected timings), Pareto
front, recommendation and the run loop with an injected renderer and clock."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from btf_addon.render.accuracy import ladder as acc
from btf_addon.render.settings import FinalMode, Lighting, RenderSettings


def _by_sweep(rungs):
    out = {}
    for r in rungs:
        out.setdefault((r.branch, r.sweep), []).append(r)
    return out


#: The knobs of the render settings' lights, samples and bounces (the first four entries):
#: the ladder, time model and run loop are tested on them (the rung counts below), and the
#: film and texel knobs apart (test_anti_aliasing_and_texel_filter_knobs).
CORE_KNOBS = acc.KNOBS[:4]
ALL_KNOBS = acc.KNOBS


@pytest.fixture(autouse=True)
def core_knobs(monkeypatch):
    monkeypatch.setattr(acc, "KNOBS", CORE_KNOBS)


def test_ladder_sweeps_each_knob_that_applies_per_final_mode():
    # Virtual Lights, 256 lights, 64 samples, 4 bounces
    base = RenderSettings(final_mode=FinalMode.VIRTUAL)
    rungs = acc.ladder(base, CORE_KNOBS)
    sweeps = _by_sweep(rungs)
    virtual = (FinalMode.VIRTUAL,)
    sampled = (FinalMode.SAMPLED,)
    assert [r.settings.lights_total for r in sweeps[virtual, "lights_total"]] == [
        4,
        16,
        64,
        256,
        1024,
    ]
    assert [r.settings.samples for r in sweeps[sampled, "samples"]] == [1, 4, 16, 64, 256]
    assert all(r.settings.max_bounces == 4 for r in sweeps[sampled, "samples"])
    # (64 samples, 4 bounces) is already in the samples sweep: kept once.
    assert [r.settings.max_bounces for r in sweeps[sampled, "max_bounces"]] == [0, 1, 2]
    assert len(rungs) == len(set(rungs)) == 5 + 5 + 3
    # Knobs that do not apply are not reported: lights in the Sampled mode, samples in Virtual.
    assert set(sweeps[virtual, "lights_total"][0].knob_values(CORE_KNOBS)) == {
        "final_mode",
        "lights_total",
    }
    assert set(sweeps[sampled, "samples"][0].knob_values(CORE_KNOBS)) == {
        "final_mode",
        "samples",
        "max_bounces",
    }


def test_anti_aliasing_and_texel_filter_knobs():
    """Anti-aliasing on/off in both modes, its subpixels only for Virtual Lights (the Sampled
    mode spreads its samples over the filter instead), the texel filter from the scene's own."""
    base = RenderSettings(final_mode=FinalMode.VIRTUAL, aa_samples=16)
    sweeps = _by_sweep(acc.ladder(base, ALL_KNOBS, base_extra={"texel_filter": "LINEAR"}))
    virtual, sampled = (FinalMode.VIRTUAL,), (FinalMode.SAMPLED,)
    for branch in (virtual, sampled):
        assert [r.settings.use_antialiasing for r in sweeps[branch, "use_antialiasing"]] == [False]
        assert [r.value("texel_filter") for r in sweeps[branch, "texel_filter"]] == ["NEAREST"]
    assert [r.settings.aa_samples for r in sweeps[virtual, "aa_samples"]] == [1, 4]
    assert (sampled, "aa_samples") not in sweeps
    off = sweeps[virtual, "use_antialiasing"][0]
    assert "aa_samples" not in off.knob_values(ALL_KNOBS)  # no subpixels without AA
    # The reference is the filtered image whatever the scene's film switch says.
    assert acc.reference_settings(replace(base, use_antialiasing=False)).use_antialiasing


def test_the_scenes_own_value_is_a_rung_and_the_headlight_has_no_knobs():
    rungs = acc.ladder(RenderSettings(lights_total=100, samples=10))
    lights = [r.settings.lights_total for r in rungs if r.sweep == "lights_total"]
    assert lights == [4, 16, 64, 100, 256, 1024]
    samples = [r.settings.samples for r in rungs if r.sweep == "samples"]
    assert samples == [1, 4, 10, 16, 64, 256]
    assert acc.ladder(RenderSettings(lighting=Lighting.HEADLIGHT)) == []


def test_a_knob_outside_render_settings_is_one_entry_and_travels_in_extra():
    """A material knob (the texel filter) needs no other code here."""
    knobs = (*CORE_KNOBS, next(k for k in ALL_KNOBS if k.name == "texel_filter"))
    rungs = acc.ladder(RenderSettings(), knobs, {"texel_filter": "NEAREST"})
    filtered = [r for r in rungs if r.sweep == "texel_filter"]
    # Both modes sweep it; the NEAREST rung equals each mode's base, already present.
    assert [(r.branch, r.value("texel_filter")) for r in filtered] == [
        ((FinalMode.VIRTUAL,), "LINEAR"),
        ((FinalMode.SAMPLED,), "LINEAR"),
    ]
    key = acc.cost_class(filtered[0], knobs)
    assert key == (("final_mode", "VIRTUAL"), ("texel_filter", "LINEAR"))


def test_relative_rmse_and_its_heat_map(rng):
    ref = rng.uniform(0.1, 1.0, (12, 16, 3))
    assert acc.relative_rmse(1.1 * ref, ref) == pytest.approx(0.1, rel=1e-12)
    noisy = ref + rng.normal(0, 0.05, ref.shape)
    error = acc.error_map(noisy, ref)
    assert error.shape == (12, 16)
    # The map's RMS is the headline number (same scale), to float rounding.
    assert np.sqrt(np.mean(error**2)) == pytest.approx(acc.relative_rmse(noisy, ref), rel=1e-12)
    # RGBA images are read as their RGB.
    rgba = np.concatenate([noisy, np.zeros((12, 16, 1))], axis=-1)
    assert acc.relative_rmse(rgba, ref) == acc.relative_rmse(noisy, ref)


def test_ssim_matches_its_closed_form_on_flat_images_and_grows_with_noise(rng):
    """Flat images: variances are 0, so SSIM = (2 μx μy + C1) / (μx² + μy² + C1) exactly (the
    displayed luminance of a grey g is srgb_encode(g))."""
    from btf_addon.core.colour import srgb_encode

    a, b = np.full((20, 20, 3), 0.2), np.full((20, 20, 3), 0.5)
    mx, my = float(srgb_encode(np.float64(0.2))), float(srgb_encode(np.float64(0.5)))
    c1 = 0.01**2  # Wang et al. 2004: (K1 · L)², L = 1 for displayed values
    expected = (2 * mx * my + c1) / (mx * mx + my * my + c1)
    assert acc.ssim_loss(a, b) == pytest.approx(1 - expected, rel=1e-9)
    assert acc.ssim_loss(a, a) == pytest.approx(0.0, abs=1e-12)
    ref = np.clip(rng.uniform(0.0, 0.8, (24, 24, 3)), 0, 1)
    noise = rng.normal(0, 1, ref.shape)
    losses = [acc.ssim_loss(np.clip(ref + s * noise, 0, None), ref) for s in (0.01, 0.05, 0.2)]
    assert losses[0] < losses[1] < losses[2]
    assert acc.ssim_loss(np.ones((3, 2, 3)), np.ones((3, 2, 3))) == pytest.approx(0.0, abs=1e-12)


def _rung(**kw) -> acc.Rung:
    """Virtual Lights unless told (the tests were written when it was the default)."""
    return acc.Rung(replace(RenderSettings(final_mode=FinalMode.VIRTUAL), **kw), "test")


def test_time_model_recovers_injected_rates_and_predicts_full_resolution():
    """Timings made from known overheads and rates per cost class (Virtual: per pixel·light;
    Sampled: per pixel·sample, one rate per bounce limit) are fitted back exactly."""
    truth = {
        (("final_mode", "VIRTUAL"),): (0.02, 500e-9),
        (("final_mode", "SAMPLED"), ("max_bounces", 0)): (0.03, 1000e-9),
        (("final_mode", "SAMPLED"), ("max_bounces", 4)): (0.03, 3000e-9),
    }
    pixels = 40 * 30
    rungs = [_rung(lights_total=n) for n in (4, 16, 64)]
    rungs += [
        _rung(final_mode=FinalMode.SAMPLED, samples=s, max_bounces=b)
        for s in (1, 4, 16)
        for b in (0, 4)
    ]
    timings = []
    for r in rungs:
        overhead, rate = truth[acc.cost_class(r)]
        timings.append(acc.Timing(r, pixels, overhead + rate * acc.work_units(r, pixels)))
    model = acc.fit_time_model(timings, setup_seconds=0.5)
    for key, (overhead, rate) in truth.items():
        assert model.classes[key][0] == pytest.approx(overhead, rel=1e-6)
        assert model.classes[key][1] == pytest.approx(rate, rel=1e-6)
    full = 1920 * 1080
    r = _rung(final_mode=FinalMode.SAMPLED, samples=256, max_bounces=4)
    assert model.predict(r, full) == pytest.approx(0.5 + 0.03 + 3000e-9 * full * 256, rel=1e-6)
    assert model.rates()["final_mode=VIRTUAL"] == pytest.approx(500, rel=1e-6)  # ns
    with pytest.raises(KeyError, match="max_bounces"):
        model.predict(_rung(final_mode=FinalMode.SAMPLED, max_bounces=2), full)


def test_time_model_with_noise_and_single_points():
    """A negative fitted intercept (noise) is dropped, the rate refitted through the origin; a
    class measured at one size borrows the median overhead of the others."""
    pixels = 100
    virtual = [_rung(lights_total=n) for n in (4, 16, 64)]
    seconds = [0.0, 0.016 * 0.9, 0.064 * 1.1]  # rate 1e-5 s per pixel·light, ±10 %
    timings = [acc.Timing(r, pixels, s) for r, s in zip(virtual, seconds, strict=True)]
    single = _rung(final_mode=FinalMode.SAMPLED, samples=8, max_bounces=2)
    timings.append(acc.Timing(single, pixels, 1.0))
    model = acc.fit_time_model(timings)
    overhead, rate = model.classes[acc.cost_class(virtual[0])]
    assert overhead >= 0 and rate == pytest.approx(1e-5, rel=0.15)
    o2, r2 = model.classes[acc.cost_class(single)]
    assert o2 == overhead and o2 + r2 * 800 == pytest.approx(1.0)


def _point(t, e, s=None):
    p = acc.Point(_rung(lights_total=int(t * 100) + 1), t, e, s if s is not None else e)
    p.predicted_seconds = t
    return p


def test_pareto_front_and_recommendation():
    points = [_point(1, 0.5), _point(2, 0.2), _point(3, 0.3), _point(4, 0.05), _point(8, 0.05)]
    assert acc.pareto_front(points) == [0, 1, 3]
    # Budget: the most accurate that fits.
    rec = acc.recommend(points, budget=3.5)
    assert (rec.index, rec.met) == (1, True)
    # Target: the fastest that reaches it (equal error: the faster one).
    assert acc.recommend(points, target=0.1).index == 3
    assert acc.recommend(points, target=0.25).index == 1
    # Both: the fastest reaching the target within the budget …
    assert acc.recommend(points, budget=5, target=0.25).index == 1
    # … else the most accurate within the budget, flagged as not met.
    rec = acc.recommend(points, budget=2.5, target=0.1)
    assert (rec.index, rec.met) == (1, False)
    # Unreachable target: the most accurate, not met; nothing in the budget: the fastest.
    assert acc.recommend(points, target=0.01) == acc.Recommendation(
        3, "no rung reaches 0.01 rmse: the most accurate", False
    )
    assert (acc.recommend(points, budget=0.5).index, acc.recommend(points, budget=0.5).met) == (
        0,
        False,
    )
    assert acc.recommend([]) is None


class FakeClock:
    """Time advances only inside the fake renderer: seconds = 0.01 + 1e-6 · work."""

    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def _fake_renderer(clock, pixels, reference, rng, cancel_after=None):
    calls = []

    def render(rung, progress):
        calls.append(rung)
        if cancel_after is not None and len(calls) > cancel_after:
            return None  # what the CL renderer returns when stopped part-way
        progress(0.5)
        clock.now += 0.01 + 1e-6 * acc.work_units(rung, pixels)
        s = rung.settings
        if rung.sweep == "reference":
            return reference
        if s.sampled:  # noise falling as 1/sqrt(samples)
            return reference + rng.normal(0, 0.3 / math.sqrt(s.samples), reference.shape)
        return reference * (1 + 1.0 / s.lights_total)  # bias falling as 1/N

    return render, calls


def test_run_scores_rungs_predicts_time_and_writes_after_each(rng):
    size, full = (16, 12), (160, 120)
    ref = rng.uniform(0.2, 1.0, (12, 16, 3))
    clock = FakeClock()
    render, _calls = _fake_renderer(clock, 16 * 12, ref, rng)
    base = RenderSettings(lights_total=64, samples=16, max_bounces=2)
    est = acc.Estimate(base, size, full, acc.reference_settings(base, samples=64))
    est.setup_seconds = 0.25
    seen, progress = [], []
    acc.run(
        est,
        acc.ladder(base),
        render,
        on_point=lambda e: seen.append(len(e.points)),
        on_progress=lambda f, _t: progress.append(f),
        clock=clock,
    )
    assert not est.interrupted and len(est.points) == est.rungs_total == 13
    assert seen == list(range(14))  # after the reference, then after every rung
    assert progress == sorted(progress) and progress[-1] == 1.0
    assert est.reference_seconds == pytest.approx(0.01 + 1e-6 * 192 * 64)
    by = {acc.describe_rung(p.rung): p for p in est.points}
    # The 1/N bias is the relative RMSE (to float32 storage of the images); time predicted
    # at 100× the pixels.
    p = by["virtual: lights_total=64"]
    assert p.rmse == pytest.approx(1 / 64, rel=1e-6)
    assert p.predicted_seconds == pytest.approx(0.25 + 0.01 + 1e-6 * 19200 * 64, rel=1e-6)
    samples = [by[f"sampled: samples={n}, max_bounces=2"].rmse for n in (1, 4, 16, 64, 256)]
    assert samples == sorted(samples, reverse=True)
    assert est.reference.seed != base.seed  # independent noise from the rungs'


def test_cancel_and_a_stopped_render_keep_what_is_done(rng):
    ref = rng.uniform(0.2, 1.0, (6, 8, 3))
    base = RenderSettings()
    clock = FakeClock()
    flag = {"stop": False}
    render, _ = _fake_renderer(clock, 48, ref, rng)
    est = acc.Estimate(base, (8, 6), (80, 60), acc.reference_settings(base, 16))

    def on_point(e):
        flag["stop"] = len(e.points) == 3

    acc.run(
        est,
        acc.ladder(base),
        render,
        on_point=on_point,
        cancelled=lambda: flag["stop"],
        clock=clock,
    )
    assert est.interrupted and len(est.points) == 3 and len(est.images) == 3
    # A render that stops part-way (its progress answered False: None) is dropped, not
    # scored, and ends the run.
    est2 = acc.Estimate(base, (8, 6), (80, 60), acc.reference_settings(base, 16))
    render2, _ = _fake_renderer(clock, 48, ref, rng, cancel_after=2)
    acc.run(est2, acc.ladder(base), render2, clock=clock)
    assert est2.interrupted and len(est2.points) == 1
    # Resuming an estimate renders only the rungs it lacks (the reference is kept).
    render3, calls = _fake_renderer(clock, 48, ref, rng)
    acc.run(est, acc.ladder(base), render3, clock=clock)
    assert len(est.points) == 13 and len(calls) == 10


def test_settings_round_trip_through_json():
    s = RenderSettings(final_mode=FinalMode.SAMPLED, samples=16, max_bounces=2)
    data = acc.settings_json(s)
    assert data["final_mode"] == "SAMPLED"
    assert acc.settings_from_json({**data, "from_a_newer_build": 1}, RenderSettings()) == s


def test_time_model_states_its_largest_residual():
    rungs = [_rung(lights_total=n) for n in (1, 2, 4)]

    def fit(seconds):
        timings = [acc.Timing(r, 10, t) for r, t in zip(rungs, seconds, strict=True)]
        return acc.fit_time_model(timings)

    assert fit([1.0, 2.0, 4.0]).residual == pytest.approx(0.0, abs=1e-9)
    # One rung 50 % slow: the least-squares line through (10, 1), (20, 3), (40, 4) is
    # t = 1/2 + (13/140)·w (by hand: Sxy = 130/3, Sxx = 1400/3); the first rung is furthest
    # from it: |1 − 10/7| / (10/7) = 0.3.
    assert fit([1.0, 3.0, 4.0]).residual == pytest.approx(0.3, rel=1e-9)


def test_verify_pools_the_recommendations_error_over_more_seeds(rng):
    """A sampled recommendation is re-rendered with other seeds (k = full ÷ preview pixels,
    at most 4) and its error becomes the pooled one: here one extra seed holds a firefly, so
    the pooled error rises past the target and the recommendation moves to the next rung."""
    ref = np.full((6, 8, 3), 0.5)
    base = RenderSettings(final_mode=FinalMode.SAMPLED, samples=16, max_bounces=2)
    est = acc.Estimate(base, (8, 6), (16, 12), acc.reference_settings(base, 64))  # k = 4
    est.reference_image = ref
    seen = []

    def render(rung, _progress):
        seen.append(rung.settings.seed)
        image = ref * (1 + 0.5 / rung.settings.samples)  # bias falling as 1/n: error 0.5/n
        if rung.settings.seed != 0 and rung.settings.samples == 64:
            image = image.copy()
            image[0, 0] = 20.0  # a firefly in every extra seed of the 64-sample rung
        return image

    for n in (16, 64, 256):
        rung = acc.Rung(replace(base, samples=n), "samples", (FinalMode.SAMPLED,))
        est.points.append(acc.Point(rung, n / 1000, 0.5 / n, 0.0, predicted_seconds=n / 100))
    assert acc.recommend(est.points, target=0.01).index == 1  # 64 samples: 0.0078
    rec = acc.verify_recommendation(est, render, target=0.01)
    p64 = est.points[1]
    assert p64.seeds == 4 and len(set(seen[:3])) == 3 and 0 not in seen[:3]
    firefly = np.mean((np.where(np.arange(48) == 0, 20.0, 0.5 * (1 + 0.5 / 64)) - 0.5) ** 2)
    expected = math.sqrt((1 * (0.5 / 64 * 0.5) ** 2 + 3 * firefly) / 4) / 0.5
    assert p64.rmse == pytest.approx(expected, rel=1e-5)  # float32 images
    assert p64.rmse_upper > p64.rmse  # the seeds disagree: the bound is above the mean
    # Now over the target: the 256-sample rung is recommended, and verified in turn.
    assert (
        rec.index == 2
        and est.points[2].seeds == 4
        and est.points[2].rmse == pytest.approx(0.5 / 256, rel=1e-5)
    )
    # Deterministic rungs are not re-rendered.
    virtual = RenderSettings(final_mode=FinalMode.VIRTUAL)
    est2 = acc.Estimate(virtual, (8, 6), (16, 12), acc.reference_settings(base, 64))
    est2.reference_image = ref
    est2.points.append(acc.Point(acc.Rung(virtual, "lights_total"), 1, 0.1, 0.1, 1.0))
    seen.clear()
    acc.verify_recommendation(est2, render)
    assert seen == [] and est2.points[0].seeds == 1 and math.isnan(est2.points[0].rmse_upper)

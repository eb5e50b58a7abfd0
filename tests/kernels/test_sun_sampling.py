"""The final render's draws of a map's sun (core/sampling/envmap.py ``Environment.sun_tables``;
kernels/render_direct.cl, "1b. The sun").

The tables are checked against their definition, computed here independently: the sun is the
pixels at least SUN_RATIO × the map's mean luminance (when they are few and hold enough of the
light above the mean), drawn ∝ its compensated weight (L − L̄) · sin θ; the environment's own
draws keep the compensated weights everywhere else and never land on the sun. The render is
checked against what the split must keep and what it is for: the mean of an independent
estimate (virtual lights drawn from the plain tables) and less noise than the same renderer
drawing the sun from the whole table."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import errors_on_and_off, sphere_with_checked_mean

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.sampling.envmap import (
    LUMINANCE,
    SUN_MAX_PIXELS,
    SUN_MIN_SHARE,
    SUN_RATIO,
    Environment,
)


def sun_in_sky(h: int = 64, w: int = 128, sun: float = 60.0) -> np.ndarray:
    """A blue sky brighter at the horizon over a dark ground, and a 3 × 3-pixel sun above it,
    like forest.exr (whose pixels above 16 × its mean hold 32 % of the light above the mean)."""
    rows = (np.arange(h) + 0.5) / h
    image = np.empty((h, w, 3))
    image[:] = np.where(rows < 0.5, 0.4 + 1.2 * rows, 0.05)[:, None, None] * [0.6, 0.8, 1.0]
    image[12:15, 80:83] = sun
    return image


def mean_and_sin(image: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    h, w = image.shape[:2]
    sin_rows = np.sin(np.pi * (np.arange(h) + 0.5) / h)[:, None]
    luminance = image @ LUMINANCE
    return luminance, float((luminance * sin_rows).sum() / (sin_rows.sum() * w)), sin_rows


def test_the_sun_and_the_tables_around_it():
    image = sun_in_sky()
    tables, sun = Environment(image).sun_tables
    luminance, mean, sin_rows = mean_and_sin(image)
    expected = np.flatnonzero(luminance >= SUN_RATIO * mean)
    assert len(expected) == 9  # the sun, not a pixel of the sky
    np.testing.assert_array_equal(sun.pixels, expected)
    weight = ((luminance - mean) * sin_rows).ravel()[expected]  # compensated, as the rest
    np.testing.assert_allclose(sun.probability, weight / weight.sum(), rtol=1e-6)
    np.testing.assert_allclose(np.diff(sun.cdf), sun.probability, rtol=1e-5, atol=1e-7)
    assert sun.cdf[0] == 0.0 and sun.cdf[-1] == 1.0
    # the environment's draws: the compensated weights, never the sun
    excess = np.maximum(luminance - mean, 0.0) * sin_rows
    excess.ravel()[expected] = 0.0
    excess /= excess.sum()
    probability = tables.row_pdf[:, None].astype(np.float64) * tables.col_pdf
    np.testing.assert_allclose(probability, excess, rtol=1e-5, atol=1e-9)  # float32 tables
    assert (probability.ravel()[expected] == 0.0).all()


def bright_window(h: int = 32, w: int = 64) -> np.ndarray:
    image = np.full((h, w, 3), 0.001)
    image[4:10, 10:24] = 10.0  # far above the mean, in 4 % of the map: not a compact source
    return image


def faint_spot(h: int = 32, w: int = 64) -> np.ndarray:
    image = sun_in_sky(h, w, sun=1.0)
    image[5, 9] = 20.0  # above 16 × the mean, with far under SUN_MIN_SHARE of the light
    return image


def sun_alone(h: int = 32, w: int = 64) -> np.ndarray:
    image = np.zeros((h, w, 3))
    image[6:8, 40:42] = 1000.0  # all the light above the mean: the compensated tables are it
    return image


@pytest.mark.parametrize(
    "image",
    [np.full((8, 16, 3), 0.7), sun_in_sky(sun=1.0), bright_window(), faint_spot(), sun_alone()],
    ids=["constant", "smooth sky", "bright window", "faint spot", "sun alone"],
)
def test_no_sun_where_none_stands_out(image):
    env = Environment(image)
    tables, sun = env.sun_tables
    assert sun is None
    for ours, compensated in zip(tables, env.mis_tables, strict=True):
        np.testing.assert_array_equal(ours, compensated)


def test_the_rule_s_bounds_hold_for_the_cases_above():
    """The cases of test_no_sun_where_none_stands_out fail the rule for the reason each is
    named for (so they test the rule, not an accident of their numbers)."""
    luminance, mean, sin_rows = mean_and_sin(bright_window())
    assert (luminance >= SUN_RATIO * mean).mean() > SUN_MAX_PIXELS
    luminance, mean, sin_rows = mean_and_sin(faint_spot())
    spot = luminance >= SUN_RATIO * mean
    excess = np.maximum(luminance - mean, 0.0) * sin_rows
    assert spot.sum() == 1 and excess[spot].sum() < SUN_MIN_SHARE * excess.sum()


@pytest.mark.opencl
@pytest.mark.parametrize(
    "btf", [LambertianBTF(0.7), GGXBTF((0.8, 0.7, 0.6), 0.3)], ids=["lambertian", "ggx"]
)
def test_sun_draws_keep_the_integral_and_cut_the_noise(cl_context, btf):
    """2048 samples: the sphere's mean within 0.5 % of 16384 virtual lights (the bound of the
    MIS test in test_render_direct.py; the lights come from the plain tables: an independent
    estimate). The GGX sphere draws the sun on its own at the camera's vertex: at 64 samples
    against a 4096-sample render its error is below 0.8 × the error with the sun drawn from the
    whole table (measured: 0.67×). The Lambertian sphere's draws pick the sun or the rest of
    the map by the sun's share, the compensated table's own density: the same noise as the
    whole table's draws within the spread of three seeds (measured 0.90×; bounds 0.75-1.33).
    A bias, a missing weight (the sun counted twice or not at all) or a wrong density fails
    one or the other."""
    env = Environment(sun_in_sky(), rotation_z_rad=0.3)
    assert env.sun_tables[1] is not None
    renderer = sphere_with_checked_mean(cl_context, env, btf)

    reference = renderer.render_sampled(4096, seed=11)[..., :3]
    errors = errors_on_and_off(renderer, reference, "sun_sampling")
    if isinstance(btf, GGXBTF):
        assert errors[True] < 0.8 * errors[False], errors
    else:
        assert 0.75 < errors[True] / errors[False] < 1.33, errors

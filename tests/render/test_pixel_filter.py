"""The film's pixel filter (render/pixel_filter.py): Cycles' profiles, their CDFs, and the
importance sampling that places anti-aliasing samples (proven against the profile)."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.render.pixel_filter import (
    FilterType,
    PixelFilter,
    r2_points,
    subpixel_offsets,
)
from btf_addon.render.settings import RenderSettings

FILTERS = [PixelFilter(t.name, w) for t in FilterType for w in (1.5, 2.5)]


def test_profiles_as_cycles_defines_them():
    """Cycles' filter_func_* with the table widths its filter_table() uses (Gaussian 3 w,
    Blackman-Harris 2 w), evaluated at the same distances: written out here independently."""
    w = 1.5
    v = np.linspace(0.0, 3.0, 61)
    bh = PixelFilter("BLACKMAN_HARRIS", w)
    t = 2 * np.pi * (v / (2 * w) + 0.5)
    cycles_bh = 0.35875 - 0.48829 * np.cos(t) + 0.14128 * np.cos(2 * t) - 0.01168 * np.cos(3 * t)
    np.testing.assert_allclose(bh.profile(v), np.where(v <= w, cycles_bh, 0.0), atol=1e-12)
    gauss = PixelFilter("GAUSSIAN", w)
    cycles_gauss = np.exp(-2.0 * (v * 6.0 / (3 * w)) ** 2)
    np.testing.assert_allclose(gauss.profile(v), np.where(v <= 1.5 * w, cycles_gauss, 0.0))
    box = PixelFilter("BOX", w)
    np.testing.assert_array_equal(box.profile(v), np.where(v <= w / 2, 1.0, 0.0))
    assert bh.radius == 1.5 and gauss.radius == 2.25 and box.radius == 0.75


@pytest.mark.parametrize("pixel_filter", FILTERS, ids=str)
def test_cdf_is_the_integral_of_the_profile(pixel_filter):
    x = np.linspace(0.0, pixel_filter.radius, 20001)
    f = pixel_filter.profile(x)
    numeric = np.concatenate([[0.0], np.cumsum((f[1:] + f[:-1]) / 2 * np.diff(x))])
    # Trapezoid rule on 20001 points: error below 1e-7 of the total for these smooth profiles.
    np.testing.assert_allclose(pixel_filter.cdf(x), numeric, atol=1e-7 * numeric[-1] + 1e-12)


@pytest.mark.parametrize("pixel_filter", FILTERS, ids=str)
def test_samples_follow_the_profile(pixel_filter, rng):
    """Chi-square of 50 000 samples in 24 bins against the normalised profile's bin masses:
    with 23 degrees of freedom a correct sampler stays below 60 with probability 1 − 1e-4; an
    offset drawn from the wrong width or shape exceeds it by orders of magnitude."""
    n = 50_000
    samples = pixel_filter.sample(rng.random(n))
    r = pixel_filter.radius
    assert np.all(np.abs(samples) <= r + 1e-9)
    edges = np.linspace(-r, r, 25)
    counts, _ = np.histogram(samples, edges)
    total = 2 * pixel_filter.cdf(r)
    cdf = 0.5 + np.sign(edges) * pixel_filter.cdf(np.abs(edges)) / total
    expected = np.diff(cdf) * n
    chi2 = float(np.sum((counts - expected) ** 2 / expected))
    assert chi2 < 60.0, chi2


def test_sampling_is_monotone_and_centred():
    """Stratified numbers stay stratified: the map is monotone, ½ is the centre, the ends are
    the support's ends."""
    u = np.linspace(0.0, 1.0 - 1e-9, 4001)
    for pixel_filter in FILTERS:
        x = pixel_filter.sample(u)
        assert np.all(np.diff(x) >= -1e-12)
        assert abs(float(pixel_filter.sample(0.5))) < 1e-6
        assert x[0] == pytest.approx(-pixel_filter.radius, abs=1e-6)


def test_subpixel_offsets_start_at_the_centre_and_spread():
    offsets = subpixel_offsets(PixelFilter(), 64)
    assert offsets.shape == (64, 2) and offsets.dtype == np.float32
    np.testing.assert_allclose(offsets[0], 0.0, atol=1e-6)  # one subpixel: the pixel centre
    # Every prefix of the R2 points is spread: each quarter of [0, 1)² holds 16 ± 2 of 64.
    points = r2_points(64)
    quarters = np.histogram2d(points[:, 0], points[:, 1], bins=2, range=[[0, 1], [0, 1]])[0]
    assert np.all(np.abs(quarters - 16) <= 2), quarters
    # The offsets' spread is the filter's: the sample variance within 5 % of the profile's.
    bh = PixelFilter()
    x = np.linspace(0, bh.radius, 20001)
    f = bh.profile(x)
    variance = float(np.sum(f * x**2)) / float(np.sum(f))  # uniform grid: the spacing cancels
    assert subpixel_offsets(bh, 256).var(axis=0) == pytest.approx([variance] * 2, rel=0.05)
    np.testing.assert_array_equal(subpixel_offsets(None, 3), np.zeros((3, 2)))


def test_bad_filters_are_refused():
    with pytest.raises(ValueError, match="pixel filter"):
        PixelFilter("MITCHELL", 1.5)
    with pytest.raises(ValueError, match="filter width"):
        PixelFilter("BOX", -1.0)


def test_settings_carry_the_film():
    assert RenderSettings().film() == PixelFilter("BLACKMAN_HARRIS", 1.5)
    assert RenderSettings(use_antialiasing=False).film() is None
    gauss = RenderSettings(pixel_filter="GAUSSIAN", filter_width=2.0).film()
    assert gauss == PixelFilter("GAUSSIAN", 2.0)


@pytest.mark.parametrize("pixel_filter", FILTERS, ids=str)
def test_the_kernels_table_is_the_inverse_cdf(pixel_filter, rng):
    """The kernels interpolate this table (btf_filter.h). Interpolated offsets follow the
    profile as the exact ones do (the same chi-square bound as above; a last entry at the
    radius, as in Cycles' table, failed it by orders of magnitude for the Gaussian), and all but
    the last cell's 0.1 % agree with the exact inverse within 1 % of the radius."""
    table = pixel_filter.table()
    assert abs(table[0]) < 1e-6 and table[-1] <= pixel_filter.radius + 1e-6
    u = rng.random(50_000)
    level = np.abs(2 * u - 1) * (len(table) - 1)
    i = np.minimum(level.astype(int), len(table) - 2)
    lerp = table[i] + (table[i + 1] - table[i]) * (level - i)
    exact = np.abs(pixel_filter.sample(u))
    assert np.percentile(np.abs(lerp - exact), 99.9) < 0.01 * pixel_filter.radius
    r = pixel_filter.radius
    edges = np.linspace(-r, r, 25)
    counts, _ = np.histogram(np.where(u < 0.5, -lerp, lerp), edges)
    cdf = 0.5 + np.sign(edges) * pixel_filter.cdf(np.abs(edges)) / (2 * pixel_filter.cdf(r))
    expected = np.diff(cdf) * len(u)
    assert float(np.sum((counts - expected) ** 2 / expected)) < 60.0

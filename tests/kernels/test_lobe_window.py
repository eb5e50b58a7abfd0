"""The lobe window (core/sampling/envmap.py ``Environment.lobe_window``,
kernels/include/btf_env_window.h, kernels/render_direct.cl "1c."): at a glossy camera vertex,
the table drawn beside the sun restricted to a window around the lobe's mirror direction.

The block sums are checked against the tables summed here another way; the rule that gives a
map a window against its definition, computed here from the radiance; the render against what
the window must keep and what it is for: the mean of an independent estimate (virtual lights
drawn from the plain tables), and less noise than the same renderer without the window, on a
map whose patchy light crosses the map's seam (the window's columns wrap there)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import errors_on_and_off, sphere_with_checked_mean, studiolights_dir

from btf_addon.core.codecs.analytic import GGXBTF, PrincipledBTF
from btf_addon.core.formats.imageio import read_exr
from btf_addon.core.sampling.envmap import (
    LUMINANCE,
    SUN_RATIO,
    WINDOW_MIN_SHARE,
    WINDOW_RATIO,
    Environment,
    lobe_window_table,
    sampling_tables,
)


def patchy_sun(h: int = 64, w: int = 128, leaves: bool = True) -> np.ndarray:
    """A sky over a dark ground, a 3 × 3-pixel sun, and around it leaves: a checkerboard of
    bright (well above WINDOW_RATIO × the mean, below SUN_RATIO) and dark pixels, like the sun
    through the trees of forest.exr (``leaves=False``: the sun in a smooth sky). Sun and leaves
    straddle the seam (columns 0 and w − 1)."""
    rows = (np.arange(h) + 0.5) / h
    image = np.empty((h, w, 3))
    image[:] = np.where(rows < 0.5, 0.3 + 0.6 * rows, 0.05)[:, None, None] * [0.6, 0.8, 1.0]
    if leaves:
        around = np.zeros((h, w), bool)
        around[8:26, :] = True
        around[:, 14 : w - 14] = False  # columns w − 14 … w − 1 and 0 … 13
        checker = (np.arange(h)[:, None] + np.arange(w)[None, :]) % 2 == 0
        image[around & checker] = 4.0
        image[around & ~checker] = 0.02
    image[15:18, [w - 1, 0, 1]] = 80.0  # the sun, across the seam
    return image


def rest_shares(image: np.ndarray) -> tuple[float, float]:
    """(the sun's share of the light above the mean, the share of the rest of it in pixels at
    least WINDOW_RATIO × the mean), from the definition."""
    h, w = image.shape[:2]
    sin_rows = np.sin(np.pi * (np.arange(h) + 0.5) / h)[:, None]
    luminance = image @ LUMINANCE
    mean = (luminance * sin_rows).sum() / (sin_rows.sum() * w)
    excess = np.maximum(luminance - mean, 0.0) * sin_rows
    sun = luminance >= SUN_RATIO * mean
    bright = (luminance >= WINDOW_RATIO * mean) & ~sun
    return excess[sun].sum() / excess.sum(), excess[bright].sum() / excess[~sun].sum()


def test_block_sums_are_the_table_summed_over_blocks():
    """A 300 × 601 map: blocks of 3 × 3 (300 / 128 rounded up), the last column of blocks
    one pixel wide. Summed here with np.add.reduceat, not the reshape of the code."""
    rng = np.random.default_rng(4)
    weight = rng.random((300, 601)) ** 8
    weight[39:42] = 0.0  # an empty row of blocks (13) keeps a CDF of zeros
    tables = sampling_tables(weight)
    window = lobe_window_table(tables)
    assert window.block == 3
    probability = tables.row_pdf[:, None] * tables.col_pdf
    sums = np.add.reduceat(
        np.add.reduceat(probability, np.arange(0, 300, 3), axis=0), np.arange(0, 601, 3), axis=1
    )
    assert sums.shape == (100, 201) and window.cdf.shape == (100, 202)
    np.testing.assert_allclose(window.row_pdf, sums.sum(axis=1), rtol=1e-5, atol=1e-12)
    filled = sums.sum(axis=1) > 0
    assert not filled[13] and (window.cdf[13] == 0.0).all()
    cdf = np.cumsum(sums[filled], axis=1) / sums[filled].sum(axis=1, keepdims=True)
    np.testing.assert_allclose(window.cdf[filled, 1:], cdf, rtol=1e-5, atol=1e-6)
    assert (np.diff(window.cdf, axis=1) >= 0.0).all()


def test_a_window_only_where_the_light_beside_the_sun_is_patchy():
    patchy, smooth = patchy_sun(), patchy_sun(leaves=False)
    # what the two maps are, by the definition
    sun_share, leaves_share = rest_shares(patchy)
    assert sun_share > 0.1 and leaves_share >= WINDOW_MIN_SHARE
    assert rest_shares(smooth)[0] > 0.1 and rest_shares(smooth)[1] < WINDOW_MIN_SHARE
    window = Environment(patchy).lobe_window
    assert window is not None and window.block == 1
    assert Environment(smooth).lobe_window is None  # a sun, but a smooth sky beside it
    assert Environment(np.full((8, 16, 3), 0.7)).lobe_window is None  # no sun at all


def test_the_bundled_maps_measured():
    """forest.exr (the sun through leaves: the window's case, docs/accuracy.md) gets a window;
    city.exr (a small sun in a smooth sky, where the window only cost) does not."""
    maps = studiolights_dir()
    assert Environment(read_exr(maps / "forest.exr")).lobe_window is not None
    assert Environment(read_exr(maps / "city.exr")).lobe_window is None


@pytest.mark.opencl
def test_the_window_keeps_the_integral_and_cuts_the_noise(cl_context):
    """A GGX sphere (roughness 0.35, the demo's) under the patchy map, turned so the leaves
    face the camera: 2048 samples within 0.5 % of 16384 virtual lights (an independent
    estimate; sphere_with_checked_mean), so the window's density, its wrap across the seam
    and the four-way weights add up; at 64 samples against a 4096-sample render its error is
    below 0.7 × the error without the window (measured 0.40×, three seeds). A non-metallic
    Principled sphere draws no window: its images are the same with and without."""
    env = Environment(patchy_sun(), rotation_z_rad=np.pi)
    assert env.lobe_window is not None
    renderer = sphere_with_checked_mean(cl_context, env, GGXBTF((0.9, 0.55, 0.2), 0.35))
    reference = renderer.render_sampled(4096, seed=11)[..., :3]
    errors = errors_on_and_off(renderer, reference, "lobe_window")
    assert errors[True] < 0.7 * errors[False], errors

    dielectric = sphere_with_checked_mean(cl_context, env, PrincipledBTF())
    images = {}
    for window in (True, False):
        dielectric.lobe_window = window
        images[window] = dielectric.render_sampled(16, seed=2)
    np.testing.assert_array_equal(images[True], images[False])

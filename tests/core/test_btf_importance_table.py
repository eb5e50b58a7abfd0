"""The sampling table's numpy side (core/sampling/btf_importance.py): the maps, the density, the
layout."""

from __future__ import annotations

import math

import numpy as np

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.codecs.packed import INT_SLOT, pack
from btf_addon.core.sampling import btf_importance as bi


def test_concentric_maps_invert_and_preserve_area(rng):
    """disk_to_square inverts square_to_disk (1e-12: float64 trig); the map is area-preserving
    up to π, so uniform square points give cosine-distributed directions: E[cos θ] = 2/3 within
    4 σ of 10⁵ samples (σ = √(1/18)/√N ≈ 7.5·10⁻⁴)."""
    s = rng.random((100_000, 2))
    np.testing.assert_allclose(bi.disk_to_square(bi.square_to_disk(s)), s, atol=1e-12)
    w = bi.square_to_hemisphere(s)
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(bi.hemisphere_to_square(w), s, atol=1e-9)
    assert abs(w[:, 2].mean() - 2 / 3) < 4 * math.sqrt(1 / 18) / math.sqrt(len(s))


def test_lambertian_table_is_cosine_sampling():
    """A constant BRDF gives D = 1 everywhere (the table is cosine sampling) to float32."""
    table = bi.build(LambertianBTF(0.7), grid=8, views=3, texels=1)
    np.testing.assert_allclose(table.density, 1.0, rtol=1e-5)


def test_ggx_table_follows_the_lobe_and_is_normalised(rng):
    """A GGX (roughness 0.2) table: mean density 1 per view (the pdf integrates to 1 exactly
    on the square), ≥ the defensive share everywhere, its largest cell near the mirror
    direction; pdf(ωi) / (cos θi / π) is the density of the cell ωi lies in (float32)."""
    table = bi.build(GGXBTF((0.8, 0.8, 0.8), 0.2), grid=16, views=5, texels=1)
    np.testing.assert_allclose(table.density.reshape(25, -1).mean(axis=1), 1.0, rtol=1e-5)
    assert table.density.min() >= bi.DEFENSIVE * (1 - 1e-6)
    wo = np.array([[math.sin(0.6), 0.0, math.cos(0.6)]])
    v = table.view_bin(wo)[0]
    row, col = np.unravel_index(np.argmax(table.density[v]), table.density[v].shape)
    peak = bi.square_to_hemisphere(np.array([[(col + 0.5) / 16, (row + 0.5) / 16]]))[0]
    mirror = np.array([-wo[0, 0], 0.0, wo[0, 2]])
    assert math.degrees(math.acos(np.clip(peak @ mirror, -1, 1))) < 20.0  # view bins are coarse
    cells = np.stack(np.meshgrid(np.arange(16), np.arange(16)), -1).reshape(-1, 2)
    s = (cells + rng.uniform(1e-6, 1 - 1e-6, cells.shape)) / 16  # one point inside each cell
    wi = bi.square_to_hemisphere(s)
    found = table.pdf(wi, np.broadcast_to(wo, wi.shape)) / (wi[:, 2] / math.pi)
    np.testing.assert_allclose(found, table.density[v][cells[:, 1], cells[:, 0]], rtol=1e-5)


def test_packed_layout_and_header():
    """CDFs rise from 0 to exactly 1 per view and row; pack(importance=True) puts the table in
    the header of measured codecs only (an analytic BTF keeps slot 0)."""
    table = bi.build(GGXBTF((0.8, 0.8, 0.8), 0.3), grid=8, views=3, texels=1)
    flat = table.packed().reshape(9, table.floats_per_view)
    rows = flat[:, 64 : 64 + 9]
    cols = flat[:, 73:].reshape(9, 8, 9)
    for cdf in (rows, cols):
        assert np.all(np.diff(cdf, axis=-1) >= 0) and np.all(cdf[..., 0] == 0)
        assert np.all(cdf[..., -1] == 1)
    assert table.nbytes == 4 * flat.size
    assert (
        pack(GGXBTF((0.8, 0.8, 0.8), 0.3), importance=True).ints.ravel()[INT_SLOT["f_importance"]]
        == 0
    )
    assert not bi.sampled_by_table(LambertianBTF(0.5))

"""Ring-grid interpolation and dense BTFs against analytic ground truth."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import random_hemisphere

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.codecs.dense import DenseBTF, tabulate
from btf_addon.core.errors import BTFFormatError
from btf_addon.core.grid import UBO2003, RingGrid, uniform_ring_grid


def test_ubo_grid_has_81_directions():
    assert UBO2003.size == 81
    theta, _ = UBO2003.angles_deg()
    assert theta.max() == 75.0


def test_weights_are_a_partition_of_unity(rng):
    theta = rng.uniform(-5, 95, 5000)
    phi = rng.uniform(-720, 720, 5000)
    idx, w = UBO2003.weights(theta, phi)
    assert w.min() >= 0 and idx.min() >= 0 and idx.max() < 81
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-12)


def test_grid_directions_reproduce_their_own_samples():
    theta, phi = UBO2003.angles_deg()
    idx, w = UBO2003.weights(theta, phi)
    values = np.arange(81, dtype=float)
    np.testing.assert_allclose((values[idx] * w).sum(axis=1), values, atol=1e-9)


def test_interpolation_is_continuous_through_the_pole_and_phi_wrap():
    values = np.random.default_rng(3).random(81)

    def f(theta, phi):
        idx, w = UBO2003.weights(np.atleast_1d(theta), np.atleast_1d(phi))
        return float((values[idx] * w).sum())

    for phi in (0.0, 97.0, 211.0):  # approaching the pole from any azimuth gives the pole value
        assert abs(f(1e-7, phi) - values[0]) < 1e-6
    assert abs(f(37.0, 360.0 - 1e-9) - f(37.0, 1e-9)) < 1e-6


def test_lambertian_interpolation_error_is_small(rng):
    """Ring-bilinear interpolation of cos θi on the UBO grid: measured 0.63% relative RMSE
    (docs/accuracy.md); 1% leaves room for the sampling of directions."""
    btf = LambertianBTF(0.8)
    dense = tabulate(btf)
    n = 20000
    wi, wo = _measured_range(rng, n), _measured_range(rng, n)
    uv = rng.random((n, 2))
    exact, approx = btf.evaluate(uv, wi, wo), dense.evaluate(uv, wi, wo)
    assert _rel_rmse(approx, exact) < 0.01


@pytest.mark.parametrize(
    ("roughness", "grid", "bound"),
    [
        (0.6, UBO2003, 0.10),  # measured 0.084
        (0.6, uniform_ring_grid(5.0), 0.02),  # measured 0.0135
        (0.3, UBO2003, 0.70),  # measured 0.61: a 5° lobe on a 15° grid
        (0.3, uniform_ring_grid(5.0), 0.25),  # measured 0.21
    ],
)
def test_ggx_interpolation_error_at_off_grid_directions(rng, roughness, grid, bound):
    """Tabulated GGX vs its exact value at random off-grid directions (θ ≤ 75°). The bounds are
    the measured errors plus ~20%: they catch a broken interpolation (which gives ≥ 100%), and
    the finer grid must beat the coarse one."""
    btf = GGXBTF(0.8, roughness)
    dense = tabulate(btf, grid, grid)
    n = 20000
    wi, wo = _measured_range(rng, n), _measured_range(rng, n)
    uv = rng.random((n, 2))
    assert _rel_rmse(dense.evaluate(uv, wi, wo), btf.evaluate(uv, wi, wo)) < bound


def test_dense_light_fades_to_zero_at_the_horizon():
    dense = tabulate(LambertianBTF(0.5))
    thetas = np.array([74.0, 75.0, 80.0, 89.0, 89.999, 90.0])
    q = np.column_stack(
        [np.full(6, 0.5), np.full(6, 0.5), thetas, np.zeros(6), np.zeros(6), np.zeros(6)]
    )
    v = dense.evaluate_angles(q)[:, 0]
    assert np.all(np.diff(v) <= 1e-9) and v[-1] == pytest.approx(0.0, abs=1e-6)
    # Continuous at the last ring (75°): the fade starts at exactly 1.
    above = dense.evaluate_angles([[0.5, 0.5, 75.0 + 1e-6, 0, 0, 0]])[0, 0]
    assert above == pytest.approx(v[1], rel=1e-5)


def test_dense_rejects_bad_data():
    with pytest.raises(BTFFormatError, match="shape"):
        DenseBTF(np.zeros((80, 81, 1, 1, 3)))
    bad = np.zeros((81, 81, 1, 1, 3))
    bad[0, 0, 0, 0, 0] = np.nan
    with pytest.raises(BTFFormatError, match="finite"):
        DenseBTF(bad)


def test_ring_grid_validation():
    with pytest.raises(ValueError):
        RingGrid((0.0, 30.0, 20.0), (1, 6, 6))
    with pytest.raises(ValueError):
        RingGrid((0.0, 95.0), (1, 6))


def _measured_range(rng, n):
    """Directions with θ ≤ 75°, where tabulated data exists."""
    d = random_hemisphere(rng, 4 * n)
    return d[d[:, 2] >= np.cos(np.radians(75.0))][:n]


def _rel_rmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b**2)))


def test_tabulate_in_light_blocks_equals_one_call_per_view(monkeypatch):
    """Tabulating in blocks of lights (a bounded working set) gives exactly the values of one
    evaluation per view: the blocks only split the same queries."""
    from btf_addon.core.codecs import dense
    from btf_addon.core.codecs.microgeometry import leather

    btf = leather(texels=4, fine_per_texel=2)
    whole = dense.tabulate(btf, UBO2003, UBO2003)
    monkeypatch.setattr(dense, "CHUNK", 50)  # 3 lights × 16 texels per block
    blocks = dense.tabulate(btf, UBO2003, UBO2003)
    np.testing.assert_array_equal(blocks.data, whole.data)

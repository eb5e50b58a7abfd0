"""Environment sampling, proven in the style of Mitsuba's envmap tests and pbrt's sampling tests."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from helpers import studiolights_dir
from scipy import stats

from btf_addon.core.formats.imageio import read_exr
from btf_addon.core.sampling.envmap import Environment
from btf_addon.core.sampling.sequences import sobol_2d


def synthetic_map(rng, h=32, w=64):
    img = rng.gamma(0.5, 1.0, size=(h, w, 3))
    img[h // 4, w // 3] = 500.0  # a sun
    return img


def bundled(name="forest"):
    return read_exr(studiolights_dir() / f"{name}.exr")


def test_chi_square_goodness_of_fit(rng):
    """Histogram of samples over image-plane bins vs the pdf's bin masses."""
    env = Environment(synthetic_map(rng))
    n = 200_000
    dirs, _, _ = env.sample(rng.random((n, 2)))
    s, t = env.image_coords(dirs)
    bins_r, bins_c = 16, 32
    observed = np.histogram2d(t, s, bins=[bins_r, bins_c], range=[[0, 1], [0, 1]])[0].ravel()
    # Expected mass per bin: sum of the pixel probabilities inside it (pdf constant per pixel).
    pixel_mass = env.row_pdf[:, None] * env.col_pdf
    expected = pixel_mass.reshape(bins_r, 2, bins_c, 2).sum(axis=(1, 3)).ravel() * n
    keep = expected > 5  # the usual validity condition of the chi-square approximation
    chi2 = (((observed - expected) ** 2) / expected)[keep].sum()
    p_value = stats.chi2.sf(chi2, keep.sum() - 1)
    assert observed[~keep].sum() <= 5 * (~keep).sum() + 5
    assert p_value > 0.01, f"chi2={chi2:.1f}, p={p_value:.2g}"


def test_pdf_integrates_to_one_over_the_sphere(rng):
    env = Environment(synthetic_map(rng), rotation_z_rad=0.7)
    n = 400_000  # uniform sphere sampling: ∫ pdf dω ≈ 4π · mean(pdf)
    z = rng.uniform(-1, 1, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - z * z)
    dirs = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    pdf = env.pdf(dirs)
    estimate = 4 * np.pi * pdf.mean()
    stderr = 4 * np.pi * pdf.std() / np.sqrt(n)
    assert abs(estimate - 1.0) < 4 * stderr + 1e-3


def test_sample_pdf_and_inverse_round_trip(rng):
    env = Environment(synthetic_map(rng), rotation_z_rad=-1.3)
    u = rng.random((5000, 2))
    dirs, radiance, pdf = env.sample(u)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(env.pdf(dirs), pdf, rtol=1e-9)
    np.testing.assert_allclose(env.invert(dirs), u, atol=1e-9)
    np.testing.assert_array_equal(env.lookup(dirs), radiance)


def test_orientation_matches_blenders_equirectangular_mapping():
    """A map that is bright only in the pixel Cycles reads for a known direction."""
    h, w = 64, 128
    for direction, rotation in (
        ((1, 0, 0), 0.0),
        ((0, -1, 0), 0.0),
        ((0.6, 0.0, 0.8), 0.0),
        ((0, 1, 0), np.pi / 2),
    ):
        d = np.asarray(direction, float) / np.linalg.norm(direction)
        # Cycles: u = (atan2(dy, dx) − π)/(−2π), v = (acos(dz) − π)/(−π) of the mapped vector
        # (direction_to_equirectangular's default range (−2π, π, −π, π)); v = 1 is the top.
        m = (
            np.array(
                [
                    [np.cos(rotation), -np.sin(rotation), 0],
                    [np.sin(rotation), np.cos(rotation), 0],
                    [0, 0, 1],
                ]
            )
            @ d
        )
        u = (np.arctan2(m[1], m[0]) - np.pi) / (-2 * np.pi)
        v = (np.arccos(m[2]) - np.pi) / (-np.pi)
        row, col = int((1 - v) * h), int(u * w) % w  # file rows run top to bottom
        img = np.zeros((h, w, 3))
        img[min(row, h - 1), col] = 1.0
        env = Environment(img, rotation_z_rad=rotation)
        lights = env.virtual_lights(16)
        assert np.all(lights.direction @ d > 0.99)


def test_virtual_light_irradiance_converges(rng):
    env = Environment(bundled("forest"))
    normals = np.array([[0, 0, 1], [1, 0, 0], [0, -1, 0], [0.3, 0.3, -0.9], [-0.5, 0.5, 0.7]])
    normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    ref = env.irradiance_reference(normals, supersample=2)
    errors = []
    for n in (25, 200, 4000):
        est = env.virtual_lights(n, seed=3).irradiance(normals)
        errors.append(float((np.abs(est - ref).sum(1) / ref.sum(1)).max()))
    print("relative irradiance error at N = 25, 200, 4000:", errors)
    assert errors[-1] < 0.01  # measured 0.39% at N = 4000 on forest (worst of five normals)
    assert errors[0] > 2 * errors[-1]


def test_every_prefix_is_stratified():
    """Power-of-two prefixes of the shifted Sobol points have one point per 2^m elementary box."""
    pts = sobol_2d(256, seed=11)
    for m in (2, 4, 6, 8):
        k = 1 << m
        prefix = pts[:k]
        for a in range(m + 1):  # boxes of 2^a × 2^(m−a)
            cells = np.floor(prefix[:, 0] * (1 << a)) * (1 << (m - a)) + np.floor(
                prefix[:, 1] * (1 << (m - a))
            )
            assert len(np.unique(cells)) == k


@pytest.mark.parametrize("name", ["zero", "sun", "nan_inf", "huge", "1x1", "2x1", "odd"])
def test_hard_maps_give_finite_bounded_lights(rng, name, caplog):
    maps = {
        "zero": np.zeros((16, 32, 3)),
        "sun": np.zeros((64, 128, 3)),
        "nan_inf": rng.random((16, 32, 3)),
        "huge": np.full((8, 16, 3), 1e6),
        "1x1": np.full((1, 1, 3), 2.0),
        "2x1": np.array([[[1.0, 1.0, 1.0]], [[3.0, 3.0, 3.0]]]),
        "odd": rng.random((7, 13, 3)),
    }
    img = maps[name]
    if name == "sun":
        img[0, 5] = 1e5  # in the pole row
    if name == "nan_inf":
        img[3, 4] = np.nan
        img[5, 6, 1] = np.inf
        img[7, 8] = -np.inf
    with caplog.at_level(logging.WARNING):
        env = Environment(img)
    lights = env.virtual_lights(64)
    for a in (lights.direction, lights.radiance, lights.pdf, lights.weights()):
        assert np.all(np.isfinite(a))
    assert np.all(lights.pdf > 0)
    normals = np.array([[0, 0, 1.0], [0, 0, -1.0], [1, 0, 0]])
    est = lights.irradiance(normals)
    ref = env.irradiance_reference(normals, supersample=8)
    assert np.all(np.isfinite(est))
    if name == "zero":
        assert np.all(est == 0)
    if name == "nan_inf":
        assert env.nonfinite_count == 3 and "3 NaN/Inf pixels" in caplog.text
    if name in ("huge", "1x1"):  # constant maps: π·L on every normal, also from the lights
        np.testing.assert_allclose(
            ref, np.broadcast_to(np.pi * img.reshape(-1, 3)[0], ref.shape), rtol=1e-3
        )
        # 64 Sobol lights leave ~4% quadrature noise on a cosine lobe; 1024 leave < 1%.
        np.testing.assert_allclose(env.virtual_lights(1024).irradiance(normals), ref, rtol=0.01)
    # Bounded weights: no light carries more than the whole map's power share it can represent.
    total = env.radiance.max() * 4 * np.pi
    assert lights.weights().max() <= total


def test_rotation_turns_the_lighting(rng):
    img = synthetic_map(rng)
    base = Environment(img)
    turned = Environment(img, rotation_z_rad=np.pi / 3)
    rz = np.array(
        [
            [np.cos(-np.pi / 3), -np.sin(-np.pi / 3), 0],
            [np.sin(-np.pi / 3), np.cos(-np.pi / 3), 0],
            [0, 0, 1],
        ]
    )
    d = rng.normal(size=(100, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    # The world sees the map turned by −γ: what base shows at d, turned shows at R(−γ)·d.
    np.testing.assert_allclose(turned.lookup(d @ rz.T), base.lookup(d))


def lamp_in_a_dim_sky(seed: int) -> np.ndarray:
    """A float32 sky (as Blender's) whose every pixel is below the mean but a small lamp's: all
    of the light above the mean is the lamp's, and sun_tables' rest is 0 (total − inside
    rounds to a few ulps or to 0 by the seed: seed 1 gave NaN tables before the rest was
    summed on its own)."""
    sky = np.random.default_rng(seed).gamma(2.0, 0.5, (32, 64, 3)).astype(np.float32)
    sky[5:7, 20:22] = 4000.0
    return sky


LAMPS = [f"lamp {seed}" for seed in range(4)]


@pytest.mark.parametrize("name", ["zero", "sun", "nan_inf", "huge", "1x1", "odd", *LAMPS])
def test_hard_maps_give_finite_final_render_tables(rng, name):
    maps = {
        "zero": np.zeros((16, 32, 3)),
        "sun": synthetic_map(rng),
        "nan_inf": np.where(rng.random((16, 32, 3)) < 0.1, np.nan, rng.random((16, 32, 3))),
        "huge": np.full((8, 16, 3), 1e6),
        "1x1": np.full((1, 1, 3), 2.0),
        "odd": rng.random((7, 13, 3)),
        **{lamp: lamp_in_a_dim_sky(seed) for seed, lamp in enumerate(LAMPS)},
    }
    with np.errstate(all="raise"):  # a 0/0 anywhere in the tables is an error here
        env = Environment(maps[name])
        tables, sun = env.sun_tables
        window = env.lobe_window
    for table in (*tables, *env.mis_tables):
        assert np.all(np.isfinite(table))
    np.testing.assert_allclose(tables.row_cdf[-1], 1.0, rtol=1e-6)
    if sun is not None:
        assert np.all(np.isfinite(sun.cdf)) and 0.0 < sun.share < 1.0
    if window is not None:
        assert np.all(np.isfinite(window.cdf))
    if name in LAMPS:  # the lamp is all there is: drawn by the compensated tables alone
        assert sun is None

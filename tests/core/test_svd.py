"""The svd codec in numpy: exact at the measured directions, continuous, colour models."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.codecs.packed import pack
from btf_addon.core.codecs.svd import colour_transform
from btf_addon.core.codecs.svd_build import factorise, reduce_resolution
from btf_addon.core.errors import BTFFormatError, UnsupportedBTFError
from btf_addon.core.formats.container import read_container, write_container
from btf_addon.core.grid import uniform_ring_grid


@pytest.fixture(scope="module")
def source():
    """A small measured-like BTF: woven microgeometry, 4×4 texels, 35 views × 80 lights."""
    return tabulate(
        woven(texels=4, fine_per_texel=4), uniform_ring_grid(20.0), uniform_ring_grid(15.0)
    )


def _queries(rng, n):
    return np.column_stack(
        [
            rng.random((n, 2)),
            rng.random(n) * 90,
            rng.random(n) * 360,
            rng.random(n) * 90,
            rng.random(n) * 360,
        ]
    )


@pytest.mark.parametrize("model", [0, 1])
def test_full_rank_equals_the_source_everywhere(source, rng, model):
    """With every component kept the factorisation is exact, and the svd codec interpolates
    exactly as the dense codec: equal at any query (float32 factors: 1e-6 of the peak)."""
    svd, errors = factorise(
        source.data * np.pi,
        source.view_grid,
        source.light_grid,
        ranks=(16, 16, 16),
        colour_model=model,
    )
    assert np.all(errors < 1e-6)
    q = _queries(rng, 4000)
    want = source.evaluate_angles(q)
    np.testing.assert_allclose(svd.evaluate_angles(q), want, atol=1e-6 * float(want.max()))


def test_truncation_error_is_reported_and_bounds_the_decode(source):
    """At the measured pairs and texel centres the decode error's RMS equals the reported
    Frobenius truncation error of each channel (RGB model: channels are R, G, B)."""
    data = source.data * np.pi
    svd, errors = factorise(
        data, source.view_grid, source.light_grid, ranks=(3, 2, 1), colour_model=0
    )
    assert np.all(errors > 0) and errors[2] >= errors[1] >= errors[0]
    nv, nl, h, w, _ = data.shape
    pair = np.repeat(np.arange(nv * nl), h * w)
    texel = np.tile(np.arange(h * w), nv * nl)
    got = svd.pair_rgb(pair, texel).reshape(nv, nl, h, w, 3)
    for c in range(3):
        rel = np.linalg.norm(got[..., c] - data[..., c]) / np.linalg.norm(data[..., c])
        assert rel == pytest.approx(errors[c], rel=1e-3)


def test_interpolation_is_continuous(source, rng):
    """A step of 1e-3° in any angle changes the value by a bounded amount (no jumps at ring
    or azimuth boundaries): ≤ 2e-3 of the peak."""
    svd, _ = factorise(source.data * np.pi, source.view_grid, source.light_grid, ranks=(4, 2, 2))
    q = _queries(rng, 3000)
    q[:, 2::2] = np.clip(q[:, 2::2], 0, 89.9)
    base = svd.evaluate_angles(q)
    for col in range(2, 6):
        moved = q.copy()
        moved[:, col] += 1e-3
        assert np.abs(svd.evaluate_angles(moved) - base).max() <= 2e-3 * base.max()


def test_colour_models_invert_their_forward_transform(rng):
    rgb = rng.random((50, 3)) + 0.1
    yuv = rgb @ np.linalg.inv(colour_transform(1).matrix).T
    np.testing.assert_allclose(colour_transform(1).apply(yuv), rgb, rtol=1e-12)
    m = rng.random((3, 3)) + np.eye(3)
    mean = rng.random(3)
    pca = colour_transform(3, m, mean)
    y = rng.random((50, 3))
    np.testing.assert_allclose(pca.apply(y), y @ m + mean)
    log = colour_transform(12, eps=1e-5)
    np.testing.assert_allclose(log.apply(np.log(rgb + 1e-5)), rgb, rtol=1e-12)
    ylog = colour_transform(9, eps=1e-5)
    y = yuv.copy()
    y[:, 0] = np.log(yuv[:, 0] + 1e-5)
    np.testing.assert_allclose(ylog.apply(y), rgb, rtol=1e-9)
    with pytest.raises(UnsupportedBTFError, match="colour model 2"):
        colour_transform(2)


def test_cosine_flag_multiplies_by_cos_theta_i(source, rng):
    a, _ = factorise(source.data * np.pi, source.view_grid, source.light_grid, ranks=(2, 2, 2))
    b, _ = factorise(
        source.data * np.pi,
        source.view_grid,
        source.light_grid,
        ranks=(2, 2, 2),
        cosine_in_data=False,
    )
    q = _queries(rng, 500)
    q[:, 2] = np.minimum(q[:, 2], 60.0)  # inside the measured rings: no fade
    ratio = np.cos(np.radians(q[:, 2]))[:, None]
    np.testing.assert_allclose(
        b.evaluate_angles(q), a.evaluate_angles(q) * ratio, rtol=1e-5, atol=1e-9
    )


def test_container_round_trip_and_packing(source, tmp_path, rng):
    svd, _ = factorise(source.data * np.pi, source.view_grid, source.light_grid, ranks=(3, 2, 1))
    path = tmp_path / "s.btfm"
    write_container(path, svd)
    back = read_container(path)
    assert back.meta.codec == "svd" and back.ranks == (3, 2, 1)
    q = _queries(rng, 500)
    np.testing.assert_array_equal(back.evaluate_angles(q), svd.evaluate_angles(q))
    tables = pack(svd)
    assert tables.floats.shape[1] == 4096


def test_nan_factors_and_bad_shapes_are_refused(source):
    svd, _ = factorise(source.data * np.pi, source.view_grid, source.light_grid, ranks=(2, 2, 2))
    u = [a.copy() for a in svd.u]
    u[1][5, 1] = np.nan
    with pytest.raises(BTFFormatError, match="channel 1: NaN"):
        type(svd)(svd.p, u, svd.sv)
    with pytest.raises(BTFFormatError, match="rows"):
        type(svd)(svd.p, [a[:-1] for a in svd.u], svd.sv)


def test_reduced_resolution_is_the_box_filtered_btf(source, rng):
    svd, _ = factorise(
        source.data * np.pi, source.view_grid, source.light_grid, ranks=(16, 16, 16), colour_model=0
    )
    half = reduce_resolution(svd, 2)
    assert (half.meta.width, half.meta.height) == (2, 2)
    q = _queries(rng, 200)
    q[:, :2] = 0.1  # texel (0, 0) of the half-size BTF = texels 0,1 × 0,1 of the source
    want = np.mean(
        [
            svd.evaluate_angles(np.column_stack([np.full((200, 2), (x, y)), q[:, 2:]]))
            for x in (0.1, 0.3)
            for y in (0.1, 0.3)
        ],
        axis=0,
    )
    np.testing.assert_allclose(half.evaluate_angles(q), want, rtol=1e-5, atol=1e-7)


def test_rotated_rings_are_exact_at_their_samples_and_continuous(rng):
    """Per-sample azimuths (rings rotated and unevenly spaced): the value at each measured
    direction pair is that pair's decode, and small steps give small changes."""
    from svd_cases import svd_cases

    btf = svd_cases()["rotated-rings"]
    p = btf.p
    vt, _ = p.view_grid.angles_deg()
    lt, _ = p.light_grid.angles_deg()
    vphi, lphi = p.phis("view"), p.phis("light")
    vi = rng.integers(0, p.view_grid.size, 300)
    li = rng.integers(0, p.light_grid.size, 300)
    li[lt[li] > 60] = 0  # inside the measured rings: no fade past the last one
    q = np.column_stack([np.full((300, 2), 0.1), lt[li], lphi[li], vt[vi], vphi[vi]])
    want = btf.pair_rgb(vi * p.light_grid.size + li, np.zeros(300, dtype=np.int64))
    np.testing.assert_allclose(
        btf.evaluate_angles(q), np.maximum(want, 0) / np.pi, rtol=1e-5, atol=1e-7
    )
    q = _queries(rng, 2000)
    q[:, 2::2] = np.clip(q[:, 2::2], 0, 89.9)
    base = btf.evaluate_angles(q)
    for col in (3, 5):
        moved = q.copy()
        moved[:, col] += 1e-3
        assert np.abs(btf.evaluate_angles(moved) - base).max() <= 2e-3 * base.max()


def test_malformed_container_params_are_one_clear_error(source):
    svd, _ = factorise(source.data * np.pi, source.view_grid, source.light_grid, ranks=(1, 1, 1))
    for broken in ({"width": "x"}, {"pca_matrix": [1, 2]}, {"view_grid": None}):
        params = {**svd.params(), **broken}
        with pytest.raises(BTFFormatError, match="svd parameters or tables are malformed"):
            type(svd).from_params(params, svd.tables())
    with pytest.raises(BTFFormatError, match="malformed"):
        type(svd).from_params(svd.params(), {"u0": svd.u[0]})

"""The SVD encoder (core/encoders/svd.py): equals the in-memory SVD, round trips at the reported
PSNR, decodes alike in numpy, OpenCL and GLSL, deterministic, degenerate inputs.

Inputs are tiny: a woven microgeometry tabulated at 4 × 4 texels on 35 views × 80 lights (the
texel-side Gram), the same at 16 × 16 texels on 7 × 7 directions (the pair-side Gram, streamed
in 50-texel blocks), a 4 × 4 MLVQ encoding. Each encode takes well under a second."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from helpers import random_queries

from btf_addon.core.codecs.dense import DenseBTF, tabulate
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.codecs.svd import SVDBTF
from btf_addon.core.codecs.svd_build import factorise
from btf_addon.core.encoders import metrics
from btf_addon.core.encoders.svd import (
    SVDSettings,
    _EvaluatedSamples,
    _MLVQSamples,
    encode_svd,
    measured_psnr,
    sizes,
    truncate,
)
from btf_addon.core.errors import BTFFormatError
from btf_addon.core.formats.container import read_container, write_container
from btf_addon.core.grid import uniform_ring_grid


@pytest.fixture(scope="module")
def source() -> DenseBTF:
    """More pairs (2800) than texels (16): the texel-side Gram."""
    return tabulate(
        woven(texels=4, fine_per_texel=4), uniform_ring_grid(20.0), uniform_ring_grid(15.0)
    )


@pytest.fixture(scope="module")
def wide() -> DenseBTF:
    """More texels (256) than pairs (49): the pair-side Gram, streamed over texel blocks."""
    grid = uniform_ring_grid(45.0)
    return tabulate(woven(texels=16, fine_per_texel=2), grid, grid)


def _product(btf: SVDBTF, c: int) -> np.ndarray:
    return btf.u[c].astype(np.float64) @ btf.sv[c].T.astype(np.float64)


@pytest.mark.parametrize("which", ["source", "wide"])
@pytest.mark.parametrize("colour", ["rgb", "yuv"])
def test_streamed_encoding_equals_the_in_memory_svd(which, colour, request):
    src = request.getfixturevalue(which)
    settings = SVDSettings(ranks=(3, 2, 1), colour_space=colour, block_texels=50, block_pairs=300)
    enc, stats = encode_svd(src, settings)
    ref, errors = factorise(
        src.data * np.pi,
        src.view_grid,
        src.light_grid,
        ranks=(3, 2, 1),
        colour_model={"rgb": 0, "yuv": 1}[colour],
    )
    assert stats.gram_side == ("texels" if which == "source" else "pairs")
    assert enc.ranks == (3, 2, 1) and enc.p.colour_model == ref.p.colour_model
    for c in range(3):
        want = _product(ref, c)
        # float32 factors on both sides: measured 2e-7 of the peak; 1e-5 leaves room.
        np.testing.assert_allclose(_product(enc, c), want, atol=1e-5 * np.abs(want).max())
    # Eigenvalues are s²: the truncation error agrees to float64 rounding of the Gram sums.
    np.testing.assert_allclose(stats.truncation_error, errors, rtol=1e-5, atol=1e-9)


def test_round_trip_meets_the_reported_psnr(source, tmp_path):
    """PSNR at the measured pairs after a container round trip is the reported one, and it is
    what the truncation error predicts (RGB: the fit's Frobenius error is the decode error at
    the samples; the decoder's clamp at 0 can only lower it)."""
    enc, stats = encode_svd(source, SVDSettings(ranks=(4, 3, 2), colour_space="rgb"))
    back = read_container(write_container(tmp_path / "s.btfm", enc))
    texels = metrics.texel_subset(4, 4, 0)
    grids = {"view_grid": source.view_grid, "light_grid": source.light_grid}
    reported = metrics.psnr(source, enc, texels, **grids)
    assert metrics.psnr(source, back, texels, **grids) == pytest.approx(reported, abs=1e-9)
    m = source.data.astype(np.float64) * np.pi  # reflectance factors; 8-bit: × 255
    norms = np.sum(m**2, axis=(0, 1, 2, 3))
    mse = 255.0**2 * float(np.sum(np.square(stats.truncation_error) * norms)) / m.size
    predicted = 10 * np.log10(255.0**2 / mse)
    # Measured equal to 1e-6 dB (no reconstruction went below 0 here); 0.01 dB: float32
    # rounding of the factors and of evaluate_angles' output.
    assert reported == pytest.approx(predicted, abs=0.01)
    assert reported > 40.0  # measured 45.4 dB: rank 4/3/2 of this woven texture


@pytest.mark.parametrize("kind", ["dense", "mlvq", "svd without cosine"])
def test_measured_psnr_is_metrics_psnr(kind, source):
    """The benchmark's fast PSNR (samples and factor products) is metrics.psnr's number."""
    if kind == "dense":
        src = source
    elif kind == "mlvq":
        from core.test_encoder_mlvq import SMALL, synthetic

        from btf_addon.core.encoders.mlvq import encode_mlvq

        src = encode_mlvq(synthetic(), SMALL)[0]
    else:
        data = source.data * np.pi
        src = factorise(data, source.view_grid, source.light_grid, (6, 4, 4), 0, "s", False)[0]
    enc, _ = encode_svd(src, SVDSettings(ranks=(2, 1, 1)))
    texels = np.array([0, 5, 6, 15])
    grids = {"view_grid": enc.p.view_grid, "light_grid": enc.p.light_grid}
    want = metrics.psnr(src, enc, texels, **grids)
    # float32 outputs of evaluate_angles against float64 products: 1e-3 dB.
    assert measured_psnr(src, enc, texels) == pytest.approx(want, abs=1e-3)
    assert 10.0 < want < 80.0  # a lossy rank: the error is really measured


def test_truncating_equals_encoding_at_the_lower_rank(source):
    high, _ = encode_svd(source, SVDSettings(ranks=(6, 4, 4)))
    low, _ = encode_svd(source, SVDSettings(ranks=(2, 1, 3)))
    cut = truncate(high, (2, 1, 3))
    for c in range(3):
        np.testing.assert_array_equal(cut.u[c], low.u[c])
        np.testing.assert_array_equal(cut.sv[c], low.sv[c])
    assert sizes(cut).stored_bytes == sum(a.nbytes for a in low.tables().values())


def test_encoding_is_deterministic(wide):
    a, _ = encode_svd(wide, SVDSettings(ranks=4, block_texels=64))
    b, _ = encode_svd(wide, SVDSettings(ranks=4, block_texels=64))
    for name, table in a.tables().items():
        np.testing.assert_array_equal(b.tables()[name], table)


def test_svd_source_reencodes_exactly_at_its_own_rank(source, rng):
    """A UBO2014-like svd input (its own grids, YUV) re-encoded at its rank decodes alike."""
    src, _ = factorise(source.data * np.pi, source.view_grid, source.light_grid, ranks=(3, 2, 2))
    enc, _ = encode_svd(src, SVDSettings(ranks=(3, 2, 2), colour_space="yuv"))
    q = random_queries(rng, 3000)
    want = src.evaluate_angles(q)
    np.testing.assert_allclose(enc.evaluate_angles(q), want, atol=1e-5 * float(want.max()))


def test_mlvq_sampler_reads_what_the_decoder_evaluates():
    """The MLVQ fast path (one decode per P4 row, then gathers) equals evaluate_angles at
    every texel, also with the material's row/column offsets."""
    from core.test_encoder_mlvq import SMALL, synthetic

    from btf_addon.core.encoders.mlvq import encode_mlvq

    mlvq, _ = encode_mlvq(synthetic(), SMALL)
    shifted = MLVQBTF(replace(mlvq.p, rows_offset=1, cols_offset=3), mlvq.tables())
    pairs = np.array([0, 7, 400, 3000, 6560])
    texels = np.arange(16)
    for btf in (mlvq, shifted):
        fast = _MLVQSamples(btf).block(pairs, texels)
        slow = _EvaluatedSamples(btf).block(pairs, texels)
        # evaluate_angles returns float32: 1e-6 of the peak.
        np.testing.assert_allclose(fast, slow, atol=1e-6 * slow.max())
        assert slow.max() > 0


@pytest.mark.opencl
def test_opencl_decodes_the_encoding_like_numpy(source, rng, cl_context):
    from btf_addon.cl.evaluate import device_btf

    enc, _ = encode_svd(source, SVDSettings(ranks=(4, 2, 2)))
    q = random_queries(rng, 20_000)
    got = device_btf(enc, cl_context).evaluate_angles(q)
    want = enc.evaluate_angles(q)
    # The svd codec's device bound (tests/kernels/test_svd_kernel.py): float32 device maths
    # within one 8-bit step of a white reflectance factor, 1e-3 relative.
    assert np.abs(got - want).max() * np.pi <= 1.0 / 255.0
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-5 * float(want.max()))
    assert want.max() > 0


def test_glsl_decodes_the_encoding_like_numpy(source, gl_ctx, rng):
    from btf_addon.gl.query import glsl_btf

    enc, _ = encode_svd(source, SVDSettings(ranks=(4, 2, 2)))
    q = random_queries(rng, 10_000)
    got, want = glsl_btf(enc, gl_ctx).evaluate_angles(q), enc.evaluate_angles(q)
    # The bound of tests/gl/test_svd_glsl.py.
    assert np.abs(got - want).max() * np.pi <= 1.0 / 255.0
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-5 * float(want.max()))
    assert want.max() > 0


# --- degenerate inputs ---------------------------------------------------------------------------
GRID = uniform_ring_grid(30.0)


def _dense(values: np.ndarray) -> DenseBTF:
    return DenseBTF(values.astype(np.float32), GRID, GRID, name="degenerate")


@pytest.mark.parametrize(
    "kind, shape",
    [("constant", (4, 4)), ("one texel", (1, 1)), ("black", (3, 2)), ("black slices", (2, 2))],
)
def test_degenerate_inputs_give_a_valid_material(kind, shape, tmp_path):
    n = GRID.size
    data = np.full((n, n, *shape, 3), 0.25)
    if kind == "one texel":
        data = np.random.default_rng(3).random(data.shape)
    elif kind == "black":
        data[:] = 0.0
    elif kind == "black slices":
        data[: n // 2] = 0.0  # every light at half of the views: black
    src = _dense(data)
    enc, stats = encode_svd(src, SVDSettings(ranks=(5, 5, 5)))
    back = read_container(write_container(tmp_path / "d.btfm", enc))
    assert all(np.all(np.isfinite(a)) for a in back.tables().values())
    assert stats.ranks == tuple([min(5, shape[0] * shape[1])] * 3)
    texels = metrics.texel_subset(*shape, 0)
    grids = {"view_grid": GRID, "light_grid": GRID}
    # The input has rank ≤ the kept rank: reproduced to float32 rounding (or exactly 0).
    value = metrics.psnr(src, back, texels, **grids)
    assert value > 100.0, value
    if kind == "black":
        assert value == np.inf
        assert not np.any(back.evaluate_angles(np.full((5, 6), 20.0)))


def test_nan_input_is_one_clear_error():
    src = _dense(np.full((GRID.size, GRID.size, 2, 2, 3), 0.5))
    src.data[3, 5, 1, 0, 2] = np.nan  # built past DenseBTF's own check, as a caller could
    with pytest.raises(BTFFormatError, match=r"NaN.*x=0, y=1"):
        encode_svd(src)


@pytest.mark.parametrize(
    "kwargs, message",
    [({"ranks": 0}, "rank"), ({"ranks": (2, 2)}, "rank"), ({"colour_space": "lab"}, "lab")],
)
def test_bad_settings_are_one_clear_error(kwargs, message):
    with pytest.raises(BTFFormatError, match=message):
        SVDSettings(**kwargs)


def test_factor_bits_quantise_each_column_and_count_the_packed_size(source):
    grids = {"view_grid": source.view_grid, "light_grid": source.light_grid}
    texels = metrics.texel_subset(4, 4, 0)
    plain, _ = encode_svd(source, SVDSettings(ranks=(4, 2, 2)))
    packed, _ = encode_svd(source, SVDSettings(ranks=(4, 2, 2), factor_bits=8))
    for a in packed.u + packed.sv:
        assert max(len(np.unique(col)) for col in a.T) <= 256
    size = sizes(packed, 8)
    entries = sum(a.size for a in packed.tables().values())
    columns = sum(a.shape[1] for a in packed.tables().values())
    assert size.packed_bytes == (entries * 8 + columns * 64 + 7) // 8
    assert size.stored_bytes == sizes(plain).stored_bytes == 4 * entries
    loss = metrics.psnr(source, plain, texels, **grids) - metrics.psnr(
        source, packed, texels, **grids
    )
    # 8-bit factors: a step of 1/255 of each column's range; measured 0.1 dB here.
    assert 0.0 <= loss < 1.0, loss


def test_ssim_is_one_when_identical_and_drops_with_texture_noise(wide):
    """metrics.ssim: 1 for the input against itself; lower when each texel is scaled by
    seeded noise (the texture's structure changes); a 1 × 1 tile compares means only."""
    assert metrics.ssim(wide, wide, n_pairs=8, **_grids(wide)) == pytest.approx(1.0, abs=1e-12)
    noise = 1.0 + 0.3 * np.random.default_rng(5).standard_normal((16, 16, 1))
    noisy = DenseBTF(np.maximum(wide.data * noise, 0.0), wide.view_grid, wide.light_grid)
    value = metrics.ssim(wide, noisy, n_pairs=8, **_grids(wide))
    assert 0.0 < value < 0.95, value
    one = DenseBTF(wide.data[:, :, :1, :1], wide.view_grid, wide.light_grid)
    dim = DenseBTF(wide.data[:, :, :1, :1] * 0.5, wide.view_grid, wide.light_grid)
    assert metrics.ssim(one, one, **_grids(wide)) == pytest.approx(1.0, abs=1e-12)
    assert metrics.ssim(one, dim, **_grids(wide)) < 1.0


def _grids(btf: DenseBTF) -> dict:
    return {"view_grid": btf.view_grid, "light_grid": btf.light_grid}

"""The MLVQ encoder's OpenCL nearest-codeword step (cl/encoder_assign.py) against numpy
(core/encoders/kmeans.py ``nearest``): same labels, same tie rule, same encoded material.

Small inputs throughout (PoCL on two cores is ~50× slower than numpy's BLAS here): about
5 seconds in all."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.encoders.kmeans import nearest

pytestmark = pytest.mark.opencl


@pytest.fixture(scope="module")
def assign():
    from btf_addon.cl.context import OpenCLUnavailableError, create_context
    from btf_addon.cl.encoder_assign import OpenCLAssign

    try:
        return OpenCLAssign(create_context())
    except OpenCLUnavailableError as exc:
        pytest.skip(f"no OpenCL device ({exc}); setup installs PoCL")


def _top_gap(x: np.ndarray, c: np.ndarray, scale_free: bool) -> np.ndarray:
    """Per row, the float64 gap between the best and second-best scores (relative)."""
    x64, c64 = x.astype(np.float64), c.astype(np.float64)
    if scale_free:
        s = np.maximum(x64 @ (c64 / np.linalg.norm(c64, axis=1)[:, None]).T, 0.0)
    else:
        s = x64 @ c64.T - 0.5 * np.einsum("kd,kd->k", c64, c64)
    if s.shape[1] < 2:
        return np.full(len(s), np.inf)
    top = np.sort(s, axis=1)[:, -2:]
    return (top[:, 1] - top[:, 0]) / np.maximum(np.abs(top[:, 1]), 1e-30)


# Sizes off the kernel's tiles (16 codewords × 64 dimensions) on purpose: partial tiles.
@pytest.mark.parametrize("n, k, d", [(300, 37, 5), (200, 70, 363), (65, 1, 130)])
@pytest.mark.parametrize("scale_free", [False, True])
def test_labels_and_scales_equal_numpy(assign, rng, n, k, d, scale_free):
    x = (rng.random((n, d)) * 100).astype(np.float32)
    c = (rng.random((k, d)) * 100).astype(np.float32)
    want, want_s = nearest(x, c, scale_free)
    got, got_s = assign(x, c, scale_free)
    assert got.dtype == np.int64 and got.shape == (n,)
    # Both sum in float32, in different orders: labels may differ only where the best two
    # scores are within 1e-5 relative (float32 rounding over ≤ 363 terms is ~1e-6).
    differ = got != want
    assert not (differ & (_top_gap(x, c, scale_free) > 1e-5)).any()
    assert differ.sum() <= max(1, n // 100)
    same = ~differ
    # The scale is computed on the host in float64 from the chosen codeword: identical.
    np.testing.assert_array_equal(got_s[same], want_s[same])


def test_ties_go_to_the_lowest_index_and_negative_rows_to_zero(assign, rng):
    """Duplicated codewords: the kernel picks the first copy (equal scores, strict >). numpy's
    BLAS may round two identical columns differently (blocked edges), so it picks *a* copy.
    Scale-free with every dot product ≤ 0: every score is 0, so index 0 with scale 0."""
    c = rng.random((5, 40)).astype(np.float32)
    c = np.concatenate([c, c])  # rows 5..9 repeat 0..4
    x = c[[3, 8, 1, 6]] + 0.01
    for scale_free in (False, True):
        got, _ = assign(x, c, scale_free)
        np.testing.assert_array_equal(got, [3, 3, 1, 1])
        np.testing.assert_array_equal(nearest(x, c, scale_free)[0] % 5, [3, 3, 1, 1])
    got, scales = assign(-x, c, True)
    np.testing.assert_array_equal(got, 0)
    np.testing.assert_array_equal(scales, 0.0)


def test_encoding_with_the_opencl_step_gives_the_numpy_material(assign):
    """The whole encoder with the device step: the same tables as numpy's on a 4×4 rough GGX
    tinted per texel (as tests/core/test_encoder_mlvq.py's), whose codewords are not near-tied."""
    from btf_addon.core.codecs.analytic import GGXBTF
    from btf_addon.core.codecs.dense import DenseBTF, tabulate
    from btf_addon.core.encoders.mlvq import MLVQSettings, encode_mlvq

    base = tabulate(GGXBTF(albedo=(0.55, 0.35, 0.2), roughness=0.6), width=1, height=1).data
    y, x = np.mgrid[0:4, 0:4]
    tint = np.where(((x + y) % 2 == 0)[..., None], [1.0, 1.0, 1.0], [0.6, 0.9, 1.3])
    src = DenseBTF(base * ((0.4 + 0.1 * (x + y))[..., None] * tint)[None, None])
    small = MLVQSettings(k1=24, k2=24, k3=8, k4=4, k_colours=4, k_index_ab=6)
    want, _ = encode_mlvq(src, small)
    got, _ = encode_mlvq(src, small, assign=assign)
    from btf_addon.core.encoders import metrics
    from btf_addon.core.encoders.mlvq import _mlvq_grid_values

    # Near-tied codewords (texels that are scaled copies of each other give duplicated
    # centres) may be picked differently by float32 sums in another order; the decoded
    # material may then differ by a rounding: measured 5e-5 of the peak at most and 1e-4 dB of
    # PSNR; bounds 1e-3 of the peak (a quarter of an 8-bit step at peak 255) and 0.01 dB.
    a, b = _mlvq_grid_values(want), _mlvq_grid_values(got)
    assert np.abs(a - b).max() <= 1e-3 * a.max()
    texels = metrics.texel_subset(4, 4, 0)
    expected = metrics.psnr(src, want, texels)
    assert metrics.psnr(src, got, texels) == pytest.approx(expected, abs=0.01)
    # The lower levels (P1, colours, 2D entries) come out identical.
    for name in ("pdf1", "ab_colors", "index_ab", "pdf2_slices", "pdf2_indices"):
        np.testing.assert_array_equal(got.tables()[name], want.tables()[name], err_msg=name)

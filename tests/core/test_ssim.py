"""The project's one SSIM (core/ssim.py) against SSIM written out per pixel from Wang et al.
2004, and both users of it (the accuracy report, the encoders' report) measuring through it."""

import math

import numpy as np
import pytest

from btf_addon.core import ssim
from btf_addon.core.codecs.dense import DenseBTF
from btf_addon.core.codecs.mlvq import LDR_VALUE_SCALE
from btf_addon.core.encoders import metrics
from btf_addon.core.grid import RingGrid
from btf_addon.render.accuracy import ladder


def _ssim_by_hand(x: np.ndarray, y: np.ndarray, peak: float) -> np.ndarray:
    """Per pixel: a normalised 2D Gaussian window (σ 1.5, radius 5) over the image reflected at
    its edges (numpy's 'reflect' padding: the edge pixel is not repeated)."""
    r = 5
    g = np.exp(-0.5 * (np.arange(-r, r + 1) / 1.5) ** 2)
    window = np.outer(g, g) / np.outer(g, g).sum()
    px, py = np.pad(x, r, mode="reflect"), np.pad(y, r, mode="reflect")
    c1, c2 = (0.01 * peak) ** 2, (0.03 * peak) ** 2
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            a, b = (
                px[i : i + 2 * r + 1, j : j + 2 * r + 1],
                py[i : i + 2 * r + 1, j : j + 2 * r + 1],
            )
            ma, mb = (window * a).sum(), (window * b).sum()
            va = (window * (a - ma) ** 2).sum()
            vb = (window * (b - mb) ** 2).sum()
            cov = (window * (a - ma) * (b - mb)).sum()
            out[i, j] = ((2 * ma * mb + c1) * (2 * cov + c2)) / (
                (ma**2 + mb**2 + c1) * (va + vb + c2)
            )
    return out


@pytest.mark.parametrize("peak", [1.0, 255.0])
def test_ssim_map_is_wang_et_al_per_pixel(peak):
    """rtol 1e-9: the same sums in another order (separable vs 2D window, E[x²] − μ² vs
    E[(x − μ)²]); the images are far from flat, so no cancellation amplifies the rounding."""
    rng = np.random.default_rng(3)
    x = rng.uniform(0, peak, (13, 17))
    y = np.clip(x + rng.normal(0, 0.2 * peak, x.shape), 0, None)
    np.testing.assert_allclose(ssim.ssim_map(x, y, peak), _ssim_by_hand(x, y, peak), rtol=1e-9)
    # Leading axes are separate images.
    stack = ssim.ssim_map(np.stack([x, y]), np.stack([y, x]), peak)
    np.testing.assert_allclose(stack[1], _ssim_by_hand(y, x, peak), rtol=1e-9)


def test_ssim_edge_cases_stay_finite():
    """Flat, zero, one-pixel and narrower-than-the-window images: finite, 1 when identical."""
    for shape in [(1, 1), (2, 3), (4, 40), (20, 20)]:
        zero = np.zeros(shape)
        assert np.all(ssim.ssim_map(zero, zero) == 1.0)
        s = ssim.ssim_map(zero, np.full(shape, 0.5))
        assert np.all(np.isfinite(s)) and np.all(s < 1.0)
    with pytest.raises(ValueError, match="two equal stacks"):
        ssim.ssim_map(np.zeros((3, 3)), np.zeros((3, 4)))


def test_the_accuracy_report_measures_through_the_one_ssim():
    rng = np.random.default_rng(4)
    ref = rng.uniform(0, 1, (16, 12, 3))
    img = np.clip(ref + rng.normal(0, 0.05, ref.shape), 0, None)
    lum = ladder.display_luminance
    expected = ssim.ssim_map(lum(img), lum(ref), peak=1.0)
    assert np.array_equal(ladder.ssim_map(img, ref), expected)


def test_the_encoders_report_measures_through_the_one_ssim():
    """metrics.ssim = the mean of core/ssim.py's map over the R, G, B texel images at the pairs
    (all 4 × 4 pairs of a 2-ring grid here). Before there was one SSIM the encoders used 7 × 7
    box windows clipped to the image: 0.83086 here against 0.83033, which this check fails."""
    grid = RingGrid((0.0, 45.0), (1, 4))
    rng = np.random.default_rng(5)
    data = rng.uniform(0, 1, (grid.size, grid.size, 12, 10, 3)).astype(np.float32)
    a = DenseBTF(data, grid, grid)
    b = DenseBTF(data * np.abs(1 + 0.3 * rng.standard_normal((1, 1, 12, 10, 1))), grid, grid)
    got = metrics.ssim(a, b, n_pairs=0, crop=0, view_grid=grid, light_grid=grid)
    tv, pv = grid.angles_deg()
    images_a, images_b = [], []
    ys, xs = np.mgrid[0:12, 0:10]  # rows = texel v (height 12), columns = u (width 10)
    uv = np.column_stack([(xs.ravel() + 0.5) / 10, (ys.ravel() + 0.5) / 12])
    for v in range(grid.size):
        for light in range(grid.size):
            q = np.column_stack([uv, np.tile([tv[light], pv[light], tv[v], pv[v]], (len(uv), 1))])
            for btf, out in ((a, images_a), (b, images_b)):
                rgb = btf.evaluate_angles(q).astype(np.float64).reshape(12, 10, 3)
                out.append(rgb.transpose(2, 0, 1) / LDR_VALUE_SCALE)
    expected = float(np.mean(ssim.ssim_map(np.array(images_a), np.array(images_b), 255.0)))
    assert math.isclose(got, expected, rel_tol=1e-12)

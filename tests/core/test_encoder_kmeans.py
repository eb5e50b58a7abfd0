"""core/encoders/kmeans.py: the float32 nearest-codeword step against a float64 brute force,
and the batched k-means++ seeding used above SEED_BATCH_FROM centres. About 2 s in all."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.encoders import kmeans as km


@pytest.mark.parametrize("scale_free", [False, True])
def test_nearest_is_the_float64_brute_force_but_near_ties(rng, scale_free):
    x = (rng.random((500, 40)) * 100 - 20).astype(np.float32)
    c = (rng.random((300, 40)) * 100 - 20).astype(np.float32)
    x64, c64 = x.astype(np.float64), c.astype(np.float64)
    if scale_free:
        dots = x64 @ c64.T
        s = np.maximum(dots, 0.0) ** 2 / np.einsum("kd,kd->k", c64, c64)
    else:
        s = -((x64[:, None, :] - c64[None]) ** 2).sum(axis=2)
    want = np.argmax(s, axis=1)
    got, scales = km.nearest(x, c, scale_free)
    top = np.sort(s, axis=1)[:, -2:]
    near_tie = (top[:, 1] - top[:, 0]) <= 1e-5 * np.abs(top[:, 1])  # float32 over 40 terms
    assert not ((got != want) & ~near_tie).any()
    if scale_free:
        best = np.maximum(dots[np.arange(500), got], 0.0) / (c64[got] ** 2).sum(axis=1)
        np.testing.assert_allclose(scales, best, rtol=1e-12)
    else:
        np.testing.assert_array_equal(scales, 1.0)


def test_batched_seeding_picks_distinct_rows_deterministically(monkeypatch):
    """Above the threshold (lowered here to keep it small) centres come in batches: still
    distinct rows of the sample (D² weights are 0 on chosen ones), the same for a seed."""
    monkeypatch.setattr(km, "SEED_BATCH_FROM", 64)
    monkeypatch.setattr(km, "SEED_ROUNDS", 8)  # batches of 63 centres
    rng = np.random.default_rng(3)
    sample = rng.random((2000, 6)).astype(np.float32)
    a = km._seed(sample, 500, np.random.default_rng(0))
    b = km._seed(sample, 500, np.random.default_rng(0))
    np.testing.assert_array_equal(a, b)
    assert len(np.unique(a, axis=0)) == 500
    # Every centre is a sample row.
    rows = {r.tobytes() for r in sample}
    assert all(r.tobytes() in rows for r in a)
    # Fewer distinct rows than centres: duplicates instead of an error (as k-means++ does).
    dup = np.repeat(sample[:10], 20, axis=0)
    c = km._seed(dup, 100, np.random.default_rng(0))
    assert len(np.unique(c, axis=0)) == 10

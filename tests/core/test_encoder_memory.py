"""The MLVQ encoder's memory: block-by-block passes give what whole-array ones give, table-coded
(factored) rows give what formed rows give, and an encode stays within the bound it states
(``mlvq.working_set_bytes``, from the block constants), measured with tracemalloc. About 3 s."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.codecs.dense import DenseBTF, tabulate
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.encoders import kmeans as km
from btf_addon.core.encoders import mlvq

SMALL = mlvq.MLVQSettings(
    k1=24, k2=24, k3=8, k4=4, k_colours=4, k_index_ab=6, k_colour_functions=8
)  # fmt: skip


@pytest.mark.parametrize("scale_free", [False, True])
def test_chunked_assignment_equals_unchunked(rng, scale_free):
    """Blocks of 37 rows, one block, and the same rows read lazily: identical labels and scales
    (each row's score row is the same product whatever the blocking)."""
    x = (rng.random((3000, 50)) * 100 - 20).astype(np.float32)
    c = (rng.random((200, 50)) * 100 - 20).astype(np.float32)
    whole = km.nearest(x, c, scale_free, rows=len(x))
    chunked = km.nearest(x, c, scale_free, rows=37)
    lazy = km.nearest(km.LazyRows(len(x), 50, lambda i: x[i].copy()), c, scale_free)
    for got in (chunked, lazy):
        np.testing.assert_array_equal(got[0], whole[0])
        np.testing.assert_array_equal(got[1], whole[1])


def test_assign_block_respects_the_row_block_whatever_d():
    """A block of rows holds at most ROW_BLOCK values (the old 4096-row block of level 4's
    40 656 values was 666 MB)."""
    for d, k in ((363, 1700), (2541, 540), (40656, 34), (10**6, 2)):
        rows = km.assign_rows(d, k)
        assert rows * d <= max(km.ROW_BLOCK, d) and rows * k <= max(km.BLOCK, 64 * k)


def test_cluster_sums_block_by_block_equal_reduceat_over_all_rows(rng, monkeypatch):
    """Blocks of 7 rows (clusters run across blocks) add in the order np.add.reduceat over the
    label-sorted rows does: the same float64 sums, bit for bit."""
    monkeypatch.setattr(km, "ROW_BLOCK", 7 * 30)
    x = (rng.random((500, 30)) * 1000).astype(np.float32) ** 2
    labels = rng.integers(0, 40, 500)
    labels[labels == 5] = 6  # an empty cluster
    counts = np.bincount(labels, minlength=40)
    order = np.argsort(labels, kind="stable")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])[counts > 0]
    want = np.add.reduceat(x[order], starts, axis=0, dtype=np.float64)
    np.testing.assert_array_equal(km.cluster_sums(x, labels, counts), want)


def test_scaled_rows_read_through_their_array(rng):
    """k-means++ products and norms of normalised rows straight from the array they index
    (all of its rows, or some): what the formed rows give, but for float32 rounding."""
    x = rng.random((500, 40)).astype(np.float32)
    c = rng.random(40).astype(np.float32)
    for rows in (np.arange(500), np.sort(rng.permutation(500)[:300])):
        scale = (rng.random(len(rows)) + 0.5).astype(np.float32)
        lazy = km.scaled_rows(x, rows, scale)
        formed = x[rows] * scale[:, None]
        np.testing.assert_array_equal(lazy[0 : len(rows)], formed)
        np.testing.assert_allclose(lazy.dots(c), formed @ c, rtol=1e-5)
        np.testing.assert_allclose(
            lazy.squared_norms(), np.einsum("nd,nd->n", formed, formed, dtype=np.float64), rtol=1e-6
        )


def factored(rng, n=300, parts=5, e=40, g=12):
    table = rng.random((e, g)).astype(np.float32)
    index = rng.integers(0, e, (n, parts))
    scale = rng.random((n, parts)).astype(np.float32) * 3
    return km.FactoredRows(table, index, scale)


def test_factored_rows_compute_what_formed_rows_do(rng):
    x = factored(rng)
    formed = x[0 : len(x)]
    assert formed.shape == x.shape == (300, 60)
    np.testing.assert_allclose(formed[7].reshape(5, 12), x.table[x.index[7]] * x.scale[7, :, None])
    w = rng.random((60, 9)).astype(np.float32)
    np.testing.assert_allclose(x.projector(w)(10, 250), formed[10:250] @ w, rtol=1e-5)
    mean, peak = x.row_stats()
    np.testing.assert_allclose(mean, formed.mean(axis=1, dtype=np.float64), rtol=1e-6)
    np.testing.assert_allclose(peak, formed.max(axis=1), rtol=1e-6)
    np.testing.assert_allclose(
        x.squared_norms(), np.einsum("nd,nd->n", formed, formed, dtype=np.float64), rtol=1e-6
    )
    labels = rng.integers(0, 11, len(x))
    counts = np.bincount(labels, minlength=12)  # cluster 11 empty
    np.testing.assert_allclose(
        x.cluster_sums(labels, counts), km.cluster_sums(formed, labels, counts), rtol=1e-6
    )
    sub = x.subset(np.array([3, 1, 4]), np.array([2.0, 0.5, 1.0]))
    np.testing.assert_allclose(sub[0:3], formed[[3, 1, 4]] * [[2.0], [0.5], [1.0]], rtol=1e-6)


@pytest.mark.parametrize("scale_free", [False, True])
def test_factored_assignment_is_the_formed_one_but_near_ties(rng, scale_free, monkeypatch):
    x = factored(rng, n=2000)
    formed = x[0 : len(x)]
    c = (rng.random((50, 60)) * 2).astype(np.float32)
    want, want_scale = km.nearest(formed, c, scale_free)
    got, scale = km.nearest(x, c, scale_free)
    w, bias, _ = km.score_weights(c, scale_free)
    s = formed.astype(np.float64) @ w.T.astype(np.float64) + bias
    top = np.sort(s, axis=1)[:, -2:]
    near_tie = (top[:, 1] - top[:, 0]) <= 1e-5 * np.abs(top[:, 1])
    assert not ((got != want) & ~near_tie).any()
    np.testing.assert_allclose(scale[got == want], want_scale[got == want], rtol=1e-5)
    monkeypatch.setattr(km, "BLOCK", 64 * 50)  # blocks of 64 rows: the same result
    again = km.nearest(x, c, scale_free)
    np.testing.assert_array_equal(again[0], got)
    np.testing.assert_array_equal(again[1], scale)


@pytest.fixture(scope="module")
def big_mlvq():
    """A 32 × 32-texel MLVQ material on the encoder's default grid (its formed grid samples:
    1024 × 162 624 bytes = 167 MB): a 4 × 4 encoding's tables, its texels tiled and scaled."""
    base = tabulate(GGXBTF(albedo=(0.55, 0.35, 0.2), roughness=0.6), width=1, height=1).data
    y, x = np.mgrid[0:4, 0:4]
    tint = np.where(((x + y) % 2 == 0)[..., None], [1.0, 1.0, 1.0], [0.6, 0.9, 1.3])
    src = DenseBTF(base * ((0.4 + 0.1 * (x + y))[..., None] * tint)[None, None], name="ggx")
    small, _ = mlvq.encode_mlvq(src, SMALL)
    t = small.tables()
    rng = np.random.default_rng(5)
    t["pdf6_slices"] = np.tile(t["pdf6_slices"], (8, 8))
    t["pdf6_scale"] = (np.tile(t["pdf6_scale"], (8, 8)) * rng.uniform(0.5, 1.5, (32, 32))).astype(
        np.float32
    )
    return MLVQBTF(small.p, t, source="tiled")


def test_encode_stays_within_its_stated_working_set(big_mlvq, monkeypatch):
    """tracemalloc's peak over a whole encode of the table-coded 32 × 32 material is within
    ``working_set_bytes`` (computed from the block constants, shrunk here) and far below the
    grid samples a formed encode holds (167 MB): no pass forms all rows. Measured: peak 8.1 MB,
    bound 30 MB."""
    monkeypatch.setattr(km, "BLOCK", 1 << 16)
    monkeypatch.setattr(km, "ROW_BLOCK", 1 << 16)
    settings = mlvq.MLVQSettings(**{**SMALL.__dict__, "iterations": 3, "train": 3000})
    n_texels = 32 * 32
    n_entries = len(big_mlvq.tables()["pdf2_indices"])
    bound = mlvq.working_set_bytes(n_texels, settings, n_entries)
    formed = mlvq.working_set_bytes(n_texels, settings)
    grid_bytes = n_texels * 16 * 7 * 11 * 11 * 3 * 4
    assert bound < grid_bytes / 4 < formed
    tracemalloc.start()
    try:
        enc, _ = mlvq.encode_mlvq(big_mlvq, settings)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak <= bound, (peak, bound)
    assert enc.t["pdf6_slices"].shape == (32, 32) and np.all(enc.t["pdf6_slices"] > 0)
    # The factored encode is the formed one's equal in quality at the grid samples.
    texels = np.arange(0, n_texels, 37)
    want = mlvq.sample_grid(big_mlvq, enc.p, None, texels)
    from btf_addon.core.encoders import metrics

    assert metrics.grid_psnr(want, mlvq._mlvq_grid_values(enc, texels)) >= 30.0

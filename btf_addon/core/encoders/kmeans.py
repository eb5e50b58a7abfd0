"""Deterministic k-means for the encoders: k-means++ seeding and Lloyd steps on a training
subsample, then (on request) one chunked assignment of every vector.

Everything is float32 (the data) with float64 sums where means are formed; the random choices
come from one ``numpy.random.Generator``, so a seed fixes the result.

Memory. Data may be an (N, D) float32 array, a :class:`LazyRows` (rows formed when read) or a
:class:`FactoredRows` (rows that are scaled rows of a small table, as a table-coded input is:
never formed; products go through the table). Every pass goes block by block, so besides the
data a k-means holds the centres and their float64 sums (K × D), one block of at most
``ROW_BLOCK`` values (float32, and float64 where sums are formed) and one of at most ``BLOCK``
scores; for factored rows, the parts × E × K table products (``FACTOR_ELEMENTS`` at most).
Nothing of size N × D is copied (``encoders.mlvq.working_set_bytes`` adds it up).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Elements (rows × centres) per distance block: a 32 MB float32 block whatever k is, so a
#: codebook of 36 000 entries does not make a 590 MB block of 4096 rows.
BLOCK = 1 << 23
#: Rows per block at most (small k).
CHUNK = 4096
#: Elements (rows × D) of data per block: a 16 MB float32 block (a 32 MB float64 copy where
#: sums are formed) whatever D is: 103 rows of the MLVQ level 4's 40 656 values.
ROW_BLOCK = 1 << 22


class LazyRows:
    """A read-only (N, D) float32 matrix whose rows are computed when asked for: ``x[a:b]``
    and ``x[indices]`` call ``rows(indices (M,) int64) -> (M, D) float32`` and return a new
    array; ``len(x)``, ``x.shape``. Passes over it (here, in :func:`nearest`, in the OpenCL
    assign step) go block by block, so only the rows of one block exist at once."""

    ndim = 2
    dtype = np.dtype(np.float32)

    def __init__(self, n: int, d: int, rows: Callable[[np.ndarray], np.ndarray]):
        self.shape = (int(n), int(d))
        self._rows = rows

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, key) -> np.ndarray:
        if isinstance(key, slice):
            index = np.arange(*key.indices(self.shape[0]), dtype=np.int64)
        else:
            index = np.asarray(key, dtype=np.int64).reshape(-1)
        return self._rows(index)


#: A factored product (``FactoredRows.projector``) keeps parts × E × K float32 products of
#: table rows and centres: at most this many (64 MB), else rows are formed block by block.
FACTOR_ELEMENTS = 1 << 24


class FactoredRows(LazyRows):
    """Rows that are runs of scaled table rows, as a table-coded input is (an MLVQ material:
    each 2D function is a stored entry times a scale): row r is ``scale[r, p] ·
    table[index[r, p]]`` for p = 0 .. parts − 1, one after another.

    ``table`` (E, g) float32 ≥ 0, ``index`` (N, parts) int64, ``scale`` (N, parts) float32 ≥ 0.
    Products with it go through the table: x @ w = Σ_p scale[:, p] · (table @ w_p)[index[:, p]]
    (``projector``: parts × E × g × K multiply-adds once instead of N × parts × g × K, and no
    row is formed); so do row norms, means, maxima and per-cluster sums. Float32 sums in
    another order than a product over formed rows: scores can swap near ties (as the OpenCL
    step can)."""

    def __init__(self, table: np.ndarray, index: np.ndarray, scale: np.ndarray):
        self.table = np.ascontiguousarray(table, dtype=np.float32)
        self.index = np.ascontiguousarray(index, dtype=np.int64)
        self.scale = np.ascontiguousarray(scale, dtype=np.float32)
        n, self.parts = self.index.shape
        super().__init__(n, self.parts * self.table.shape[1], self._form)

    def _form(self, rows: np.ndarray) -> np.ndarray:
        out = self.table[self.index[rows]]  # (M, parts, g)
        out *= self.scale[rows][..., None]
        return out.reshape(len(rows), self.shape[1])

    def subset(self, rows: np.ndarray, factor: np.ndarray | None = None) -> FactoredRows:
        """Rows ``rows`` (times ``factor`` (len(rows),) per row), still factored."""
        scale = self.scale[rows]
        if factor is not None:
            scale = scale * np.asarray(factor, dtype=np.float32)[:, None]
        return FactoredRows(self.table, self.index[rows], scale)

    def factored(self, k: int) -> bool:
        """Whether a product with ``k`` centres goes through the table (FACTOR_ELEMENTS)."""
        return self.parts * len(self.table) * max(1, k) <= FACTOR_ELEMENTS

    def projector(self, w: np.ndarray) -> Callable[[int, int], np.ndarray]:
        """``proj(a, b)`` = x[a:b] @ w (float32 (b − a, K)) for ``w`` (D, K) float32: one
        product table (E, g) @ w as (g, parts · K), then per part a gather of its rows."""
        e, g = self.table.shape
        k = np.shape(w)[1]
        w = np.asarray(w, dtype=np.float32).reshape(self.parts, g, k).transpose(1, 0, 2)
        products = (self.table @ w.reshape(g, self.parts * k)).reshape(e, self.parts, k)
        products = np.ascontiguousarray(products.transpose(1, 0, 2))  # (parts, E, K)

        def proj(a: int, b: int) -> np.ndarray:
            index, scale = self.index[a:b], self.scale[a:b]
            out = np.take(products[0], index[:, 0], axis=0)
            out *= scale[:, 0, None]
            term = np.empty_like(out)
            for p in range(1, self.parts):
                np.take(products[p], index[:, p], axis=0, out=term)
                term *= scale[:, p, None]
                out += term
            return out

        return proj

    def row_stats(self) -> tuple[np.ndarray, np.ndarray]:
        """Per row: the mean (float64) and the maximum (float32)."""
        t64 = self.table.astype(np.float64)
        scale = self.scale.astype(np.float64)
        mean = np.einsum("np,np->n", scale, t64.sum(axis=1)[self.index]) / self.shape[1]
        peak = (scale * self.table.max(axis=1, initial=0.0)[self.index]).max(axis=1)
        return mean, peak.astype(np.float32)

    def squared_norms(self) -> np.ndarray:
        """‖x_r‖² (float64, (N,)) (different table rows of a run occupy disjoint columns)."""
        t64 = self.table.astype(np.float64)
        norms = np.einsum("eg,eg->e", t64, t64)
        return np.einsum("np,np->n", self.scale.astype(np.float64) ** 2, norms[self.index])

    def cluster_sums(self, labels: np.ndarray, counts: np.ndarray) -> np.ndarray:
        """Float64 sums of the rows per non-empty cluster. Per part, the scales are summed per
        (cluster, table row) pair present (at most N pairs, found by sorting: nothing of size
        K × E), then each cluster adds its pairs' weighted table rows, ROW_BLOCK values at a
        time."""
        filled = np.flatnonzero(counts)
        slot = np.full(len(counts), -1, dtype=np.int64)
        slot[filled] = np.arange(len(filled))
        e, g = self.table.shape
        t64 = self.table.astype(np.float64)
        sums = np.zeros((len(filled), self.shape[1]), dtype=np.float64)
        base = slot[labels] * e
        step = row_block(g)
        for p in range(self.parts):
            key = base + self.index[:, p]
            order = np.argsort(key, kind="stable")
            key = key[order]
            first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
            weights = np.add.reduceat(self.scale[order, p].astype(np.float64), first)
            pairs = key[first]  # sorted: cluster-major
            for a in range(0, len(pairs), step):
                part = pairs[a : a + step]
                cluster = part // e
                rows = t64[part % e]
                rows *= weights[a : a + step, None]
                starts = np.flatnonzero(np.r_[True, cluster[1:] != cluster[:-1]])
                sums[cluster[starts], p * g : (p + 1) * g] += np.add.reduceat(rows, starts, axis=0)
        return sums


def take_rows(x: np.ndarray | LazyRows, rows: np.ndarray) -> np.ndarray | FactoredRows:
    """``x[rows]``: factored rows stay factored, anything else is formed (float32)."""
    if isinstance(x, FactoredRows):
        return x.subset(rows)
    return np.asarray(x[rows], dtype=np.float32)


def scaled_rows(x: np.ndarray | LazyRows, rows: np.ndarray, scale: np.ndarray) -> LazyRows:
    """``x[rows] * scale[:, None]`` (float32, (len(rows), D)) without forming it: factored rows
    stay factored, anything else becomes :class:`ScaledRows`."""
    rows = np.asarray(rows, dtype=np.int64)
    scale = np.asarray(scale, dtype=np.float32)
    if isinstance(x, FactoredRows):
        return x.subset(rows, scale)
    return ScaledRows(x, rows, scale)


class ScaledRows(LazyRows):
    """``x[rows] * scale[:, None]`` of an array or :class:`LazyRows` ``x``, formed a block at a
    time when read. Products with one vector (k-means++ seeding) and row norms go through
    ``x`` itself: (x[rows] @ c) · scale, straight on x when ``rows`` are all of its rows."""

    def __init__(self, x: np.ndarray | LazyRows, rows: np.ndarray, scale: np.ndarray):
        self.base, self.rows, self.scale = x, rows, scale
        self._all = len(rows) == len(x) and np.array_equal(rows, np.arange(len(x)))
        super().__init__(len(rows), x.shape[1], self._form)

    def _form(self, index: np.ndarray) -> np.ndarray:
        out = np.asarray(self.base[self.rows[index]], dtype=np.float32)
        out *= self.scale[index, None]
        return out

    def _base_blocks(self):
        if self._all and isinstance(self.base, np.ndarray):
            yield 0, self.base
            return
        step = row_block(self.shape[1])
        for a in range(0, len(self.rows), step):
            yield a, np.asarray(self.base[self.rows[a : a + step]], dtype=np.float32)

    def dots(self, c: np.ndarray) -> np.ndarray:
        """x[rows] · scale @ c (float32, (N,))."""
        out = np.empty(len(self.rows), dtype=np.float32)
        for a, xs in self._base_blocks():
            out[a : a + len(xs)] = xs @ c
        return out * self.scale

    def squared_norms(self) -> np.ndarray:
        """‖x[rows] · scale‖² (float64, (N,))."""
        out = np.empty(len(self.rows), dtype=np.float64)
        for a, xs in self._base_blocks():
            for b in range(0, len(xs), row_block(self.shape[1])):
                part = xs[b : b + row_block(self.shape[1])]
                out[a + b : a + b + len(part)] = np.einsum("nd,nd->n", part, part, dtype=np.float64)
        return out * self.scale.astype(np.float64) ** 2


def row_block(d: int) -> int:
    """Rows of D values per data block: ROW_BLOCK // D, at least 1."""
    return max(1, ROW_BLOCK // max(1, d))


def blocks(x: np.ndarray | LazyRows, rows: int | None = None):
    """``(start, x[start:start + rows] as float32)`` over ``x``; ``rows`` default
    :func:`row_block`."""
    n, d = x.shape
    rows = row_block(d) if rows is None else rows
    for start in range(0, n, rows):
        yield start, np.asarray(x[start : start + rows], dtype=np.float32)


def row_stats(x: np.ndarray | LazyRows) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``x`` (N, D): the mean (float64) and the maximum (float32), block by block."""
    if isinstance(x, FactoredRows):
        return x.row_stats()
    n = len(x)
    mean = np.empty(n, dtype=np.float64)
    peak = np.empty(n, dtype=np.float32)
    for start, xs in blocks(x):
        mean[start : start + len(xs)] = xs.mean(axis=1, dtype=np.float64)
        peak[start : start + len(xs)] = xs.max(axis=1)
    return mean, peak


#: ``assign(x (N, D), centres (K, D), scale_free) -> (labels (N,) int64, scales (N,) float64)``:
#: the nearest-centre step, injectable so that a device back end (cl/encoder_assign.py) can
#: replace :func:`nearest` without core/ importing it. ``x`` may be a :class:`LazyRows`:
#: an assign step reads it by slices ``x[a:b]``.
Assign = Callable[[np.ndarray, np.ndarray, bool], tuple[np.ndarray, np.ndarray]]


def block_rows(k: int) -> int:
    """Rows per distance block for ``k`` centres (at least 64, at most CHUNK)."""
    return max(64, min(CHUNK, BLOCK // max(1, k)))


def score_weights(
    centres: np.ndarray, scale_free: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the nearest codeword maximises, score = ⟨x, w_c⟩ + bias_c (scale-free: clamped at
    0). Returns w (K, D) float32, bias (K,) float32, ‖c‖² (K,) float64.

    Plain: ‖x‖² is the same for every centre, so argmin ‖x − c‖² = argmax ⟨x, c⟩ − ‖c‖²/2.
    Scale-free: ⟨x, c⟩₊² / ‖c‖² is monotonic in ⟨x, c⟩₊ / ‖c‖: unit centres (a zero centre
    scores 0)."""
    c = np.ascontiguousarray(centres, dtype=np.float32)
    cc = np.einsum("kd,kd->k", c, c, dtype=np.float64)
    if scale_free:
        inv = np.divide(1.0, np.sqrt(cc), out=np.zeros_like(cc), where=cc > 0)
        return c * inv[:, None].astype(np.float32), np.zeros(len(c), np.float32), cc
    return c, (-0.5 * cc).astype(np.float32), cc


def best_scales(x: np.ndarray, centres: np.ndarray, cc: np.ndarray, best: np.ndarray) -> np.ndarray:
    """The least-squares non-negative scale of each row of ``x`` (N, D) on its chosen centre
    ``centres[best]``, in float64 (N,); 0 for a zero centre."""
    d = np.einsum("nd,nd->n", x, centres[best], dtype=np.float64)
    c2 = cc[best]
    return np.divide(np.maximum(d, 0.0), c2, out=np.zeros(len(x)), where=c2 > 0)


def assign_rows(d: int, k: int) -> int:
    """Rows per block of :func:`nearest`: ``block_rows(k)`` score rows, and no more than
    ``row_block(d)`` rows of data (the block and its chosen centres stay within ROW_BLOCK
    elements each whatever D is)."""
    return max(1, min(block_rows(k), row_block(d)))


def nearest(
    x: np.ndarray | LazyRows,
    centres: np.ndarray,
    scale_free: bool = False,
    rows: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Index of the closest centre for every row of ``x`` (N, D) among ``centres`` (K, D).

    ``scale_free``: closest after the best non-negative scale of the centre (minimises
    ‖x − s·c‖² over s ≥ 0); returns that scale too. Otherwise the plain Euclidean nearest
    centre and a scale of 1. Returns (N,) int64, (N,) float64.

    Per block of ``rows`` rows (default :func:`assign_rows`) one float32 matrix product
    (``score_weights``) and one argmax: ties and the all-non-positive scale-free case go to the
    lowest index. Each row's result does not depend on the blocking. Float32 scores can swap
    centres whose scores differ by ~1e-7 relative (near ties); the scale is float64."""
    n = len(x)
    labels = np.zeros(n, dtype=np.int64)
    scales = np.ones(n, dtype=np.float64)
    c = np.ascontiguousarray(centres, dtype=np.float32)
    w, bias, cc = score_weights(c, scale_free)
    wt = w.T.copy()
    rows = assign_rows(c.shape[1], len(c)) if rows is None else rows
    if isinstance(x, FactoredRows) and x.factored(len(c)):
        _nearest_factored(x, wt, bias, cc, scale_free, block_rows(len(c)), labels, scales)
        return labels, scales
    for start, xs in blocks(x, rows):
        scores = xs @ wt
        scores += bias
        if scale_free:
            np.maximum(scores, 0.0, out=scores)
        best = np.argmax(scores, axis=1)
        labels[start : start + len(xs)] = best
        if scale_free:
            scales[start : start + len(xs)] = best_scales(xs, c, cc, best)
    return labels, scales


def _nearest_factored(x, wt, bias, cc, scale_free, rows, labels, scales) -> None:
    """:func:`nearest` on :class:`FactoredRows` through ``x.projector``: the same scores and
    tie rule; the scale from the chosen score, ⟨x, c⟩ = score · ‖c‖ (float32 score)."""
    proj = x.projector(wt)
    norm = np.sqrt(cc)
    for start in range(0, len(x), rows):
        scores = proj(start, min(len(x), start + rows))
        scores += bias
        if scale_free:
            np.maximum(scores, 0.0, out=scores)
        best = np.argmax(scores, axis=1)
        labels[start : start + len(best)] = best
        if scale_free:
            dot = scores[np.arange(len(best)), best].astype(np.float64) * norm[best]
            c2 = cc[best]
            scales[start : start + len(best)] = np.divide(
                dot, c2, out=np.zeros(len(best)), where=c2 > 0
            )


def kmeans(
    x: np.ndarray | LazyRows,
    k: int,
    rng: np.random.Generator,
    iterations: int = 10,
    train: int = 20000,
    cancel: Callable[[], None] | None = None,
    assign: Assign = nearest,
    *,
    labels: bool = True,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Cluster ``x`` (N, D) float32 (an array or :class:`LazyRows`) into at most ``k`` centres.

    Returns (centres (K', D) float32, labels (N,) int64), K' = min(k, N); ``labels=False``
    skips the final assignment of every row and returns None for them. Centres are trained
    on a subsample of ``train`` rows (all rows when fewer); an empty cluster is re-seeded with
    the training row farthest from its centre. ``cancel`` is called between steps (it raises
    to stop). ``assign`` is the nearest-centre step (default :func:`nearest`)."""
    if not isinstance(x, LazyRows):
        x = np.asarray(x, dtype=np.float32)
    n = len(x)
    k = max(1, min(int(k), n))
    if k == n:
        return np.array(x[0:n], dtype=np.float32), np.arange(n, dtype=np.int64)
    sample = x if n <= train else take_rows(x, np.sort(rng.choice(n, train, replace=False)))
    centres = _seed(sample, k, rng)
    for _ in range(iterations):
        if cancel is not None:
            cancel()
        found, _ = assign(sample, centres, False)
        counts = np.bincount(found, minlength=k)
        filled = counts > 0
        sums = cluster_sums(sample, found, counts)
        centres[filled] = (sums / counts[filled, None]).astype(np.float32)
        if not filled.all():
            err = _squared_errors(sample, centres, found)
            far = np.argsort(-err, kind="stable")[: int((~filled).sum())]
            centres[~filled] = sample[far]
    if not labels:
        return centres, None
    found, _ = assign(x, centres, False)
    return centres, found


def cluster_sums(x: np.ndarray | LazyRows, labels: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Float64 sums of the rows of ``x`` (N, D) per non-empty cluster (in cluster order):
    (number of clusters with counts > 0, D). The rows of a cluster are added one after another
    in row order (as ``np.add.reduceat`` over the rows sorted by label), block by block:
    a float64 copy of one block, never of all of x. :class:`FactoredRows` through its table."""
    if isinstance(x, FactoredRows):
        return x.cluster_sums(labels, counts)
    d = x.shape[1]
    order = np.argsort(labels, kind="stable")
    filled = np.flatnonzero(counts)
    slot = np.full(len(counts), -1, dtype=np.int64)
    slot[filled] = np.arange(len(filled))
    sums = np.zeros((len(filled), d), dtype=np.float64)
    carry_label = -1
    rows = row_block(d)
    for start in range(0, len(order), rows):
        part = order[start : start + rows]
        block = np.asarray(x[part], dtype=np.float64)
        lab = labels[part]
        if lab[0] == carry_label:  # the cluster runs on from the previous block
            block[0] += sums[slot[carry_label]]
        first = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
        sums[slot[lab[first]]] = np.add.reduceat(block, first, axis=0)
        carry_label = int(lab[-1])
    return sums


def _squared_errors(x: np.ndarray | LazyRows, centres: np.ndarray, labels: np.ndarray):
    """‖x_n − centres[labels_n]‖² (float32, (N,)) block by block (factored rows formed a
    block at a time: N × D work, less than one product through the table)."""
    err = np.empty(len(x), dtype=np.float32)
    for start, xs in blocks(x):
        diff = xs - centres[labels[start : start + len(xs)]]
        err[start : start + len(xs)] = np.einsum("nd,nd->n", diff, diff)
    return err


#: k-means++ picks one centre per pass over the sample; above this k it picks a batch per pass
#: (D²-weighted, without replacement) in SEED_ROUNDS passes: one matrix product per batch
#: instead of k matrix-vector products (36 000 passes over 100 000 rows took most of an hour).
SEED_BATCH_FROM = 4096
SEED_ROUNDS = 256


def _seed(sample: np.ndarray | LazyRows, k: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ seeding (Arthur & Vassilvitskii 2007) on ``sample``; duplicates of a chosen
    row have zero weight, so identical rows never become two centres unless nothing else is
    left. Above SEED_BATCH_FROM centres, batches of ceil(k / SEED_ROUNDS) per round."""
    n = len(sample)
    centres = np.empty((k, sample.shape[1]), dtype=np.float32)
    first = int(rng.integers(n))
    centres[0] = sample[first : first + 1][0]
    # ‖x − c‖² = ‖x‖² − 2⟨x, c⟩ + ‖c‖²: one matrix-vector product per centre.
    if isinstance(sample, FactoredRows):
        xx = sample.squared_norms()

        def dots(c: np.ndarray) -> np.ndarray:
            return sample.projector(c[:, None])(0, n)[:, 0]

    elif isinstance(sample, ScaledRows):
        xx = sample.squared_norms()
        dots = sample.dots

    elif isinstance(sample, LazyRows):
        xx = np.concatenate(
            [np.einsum("nd,nd->n", xs, xs, dtype=np.float64) for _, xs in blocks(sample)]
        )

        def dots(c: np.ndarray) -> np.ndarray:
            return np.concatenate([xs @ c for _, xs in blocks(sample)])

    else:
        xx = np.einsum("nd,nd->n", sample, sample, dtype=np.float64)

        def dots(c: np.ndarray) -> np.ndarray:
            return sample @ c

    def dist2(c: np.ndarray) -> np.ndarray:
        cc = float(np.dot(c.astype(np.float64), c))
        return np.maximum(xx - 2.0 * dots(c).astype(np.float64) + cc, 0.0)

    d2 = dist2(centres[0])
    if k > SEED_BATCH_FROM:
        return _seed_batched(sample, centres, d2, xx, rng)
    for i in range(1, k):
        total = d2.sum()
        pick = int(rng.choice(n, p=d2 / total)) if total > 0 else int(rng.integers(n))
        centres[i] = sample[pick : pick + 1][0]
        d2 = np.minimum(d2, dist2(centres[i]))
    return centres


def _seed_batched(sample, centres, d2, xx, rng) -> np.ndarray:
    """The rest of ``centres`` (row 0 chosen, ``d2`` its squared distances) in batches."""
    n, k = len(sample), len(centres)
    batch = -(-k // SEED_ROUNDS)
    filled = 1
    rows = CHUNK if isinstance(sample, np.ndarray) else min(CHUNK, row_block(sample.shape[1]))
    while filled < k:
        m = min(batch, k - filled)
        positive = int(np.count_nonzero(d2))
        if positive >= m:
            picks = rng.choice(n, m, replace=False, p=d2 / d2.sum())
        else:  # fewer distinct rows left than centres wanted: duplicates, as k-means++ does
            picks = rng.integers(n, size=m)
        new = np.asarray(sample[picks], dtype=np.float32)
        centres[filled : filled + m] = new
        filled += m
        cc = np.einsum("kd,kd->k", new, new, dtype=np.float64)
        if isinstance(sample, FactoredRows) and sample.factored(m):
            proj = sample.projector(new.T)
            parts = ((a, proj(a, min(n, a + CHUNK))) for a in range(0, n, CHUNK))
            rows = CHUNK
        else:
            parts = ((a, xs @ new.T) for a, xs in blocks(sample, rows))
        for start, dots in parts:
            d = xx[start : start + rows, None] - 2.0 * dots
            d2[start : start + rows] = np.minimum(
                d2[start : start + rows], np.maximum((d + cc).min(axis=1), 0.0)
            )
    return centres

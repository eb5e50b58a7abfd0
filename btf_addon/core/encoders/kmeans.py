"""Deterministic k-means for the encoders: k-means++ seeding and Lloyd steps on a training
subsample, then one chunked assignment of every vector.

Everything is float32 (the data) with float64 sums where means are formed; the random choices
come from one ``numpy.random.Generator``, so a seed fixes the result.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Elements (rows × centres) per distance block: a 32 MB float32 block whatever k is, so a
#: codebook of 36 000 entries does not make a 590 MB block of 4096 rows.
BLOCK = 1 << 23
#: Rows per block at most (small k).
CHUNK = 4096

#: ``assign(x (N, D), centres (K, D), scale_free) -> (labels (N,) int64, scales (N,) float64)``:
#: the nearest-centre step, injectable so that a device back end (cl/encoder_assign.py) can
#: replace :func:`nearest` without core/ importing it.
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


def nearest(
    x: np.ndarray, centres: np.ndarray, scale_free: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Index of the closest centre for every row of ``x`` (N, D) among ``centres`` (K, D).

    ``scale_free``: closest after the best non-negative scale of the centre (minimises
    ‖x − s·c‖² over s ≥ 0); returns that scale too. Otherwise the plain Euclidean nearest
    centre and a scale of 1. Returns (N,) int64, (N,) float64.

    Per block of rows one float32 matrix product (``score_weights``) and one argmax: ties
    and the all-non-positive scale-free case go to the lowest index. Float32 scores can swap
    centres whose scores differ by ~1e-7 relative (near ties); the scale is float64."""
    n = len(x)
    labels = np.zeros(n, dtype=np.int64)
    scales = np.ones(n, dtype=np.float64)
    c = np.ascontiguousarray(centres, dtype=np.float32)
    w, bias, cc = score_weights(c, scale_free)
    wt = w.T.copy()
    rows = block_rows(len(c))
    for start in range(0, n, rows):
        xs = np.asarray(x[start : start + rows], dtype=np.float32)
        scores = xs @ wt
        scores += bias
        if scale_free:
            np.maximum(scores, 0.0, out=scores)
        best = np.argmax(scores, axis=1)
        labels[start : start + len(xs)] = best
        if scale_free:
            scales[start : start + len(xs)] = best_scales(xs, c, cc, best)
    return labels, scales


def kmeans(
    x: np.ndarray,
    k: int,
    rng: np.random.Generator,
    iterations: int = 10,
    train: int = 20000,
    cancel: Callable[[], None] | None = None,
    assign: Assign = nearest,
) -> tuple[np.ndarray, np.ndarray]:
    """Cluster ``x`` (N, D) float32 into at most ``k`` centres.

    Returns (centres (K', D) float32, labels (N,) int64), K' = min(k, N). Centres are trained
    on a subsample of ``train`` rows (all rows when fewer); an empty cluster is re-seeded with
    the training row farthest from its centre. ``cancel`` is called between steps (it raises
    to stop). ``assign`` is the nearest-centre step (default :func:`nearest`)."""
    x = np.asarray(x, dtype=np.float32)
    n = len(x)
    k = max(1, min(int(k), n))
    if k == n:
        return x.copy(), np.arange(n, dtype=np.int64)
    sample = x if n <= train else x[np.sort(rng.choice(n, train, replace=False))]
    centres = _seed(sample, k, rng)
    for _ in range(iterations):
        if cancel is not None:
            cancel()
        labels, _ = assign(sample, centres, False)
        counts = np.bincount(labels, minlength=k)
        filled = counts > 0
        order = np.argsort(labels, kind="stable")
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])[filled]
        sums = np.add.reduceat(sample[order], starts, axis=0, dtype=np.float64)
        centres[filled] = (sums / counts[filled, None]).astype(np.float32)
        if not filled.all():
            err = np.einsum("nd,nd->n", sample - centres[labels], sample - centres[labels])
            far = np.argsort(-err, kind="stable")[: int((~filled).sum())]
            centres[~filled] = sample[far]
    labels, _ = assign(x, centres, False)
    return centres, labels


#: k-means++ picks one centre per pass over the sample; above this k it picks a batch per pass
#: (D²-weighted, without replacement) in SEED_ROUNDS passes: one matrix product per batch
#: instead of k matrix-vector products (36 000 passes over 100 000 rows took most of an hour).
SEED_BATCH_FROM = 4096
SEED_ROUNDS = 256


def _seed(sample: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ seeding (Arthur & Vassilvitskii 2007) on ``sample``; duplicates of a chosen
    row have zero weight, so identical rows never become two centres unless nothing else is
    left. Above SEED_BATCH_FROM centres, batches of ceil(k / SEED_ROUNDS) per round."""
    n = len(sample)
    centres = np.empty((k, sample.shape[1]), dtype=np.float32)
    first = int(rng.integers(n))
    centres[0] = sample[first]
    # ‖x − c‖² = ‖x‖² − 2⟨x, c⟩ + ‖c‖²: one matrix-vector product per centre.
    xx = np.einsum("nd,nd->n", sample, sample, dtype=np.float64)

    def dist2(c: np.ndarray) -> np.ndarray:
        cc = float(np.dot(c.astype(np.float64), c))
        return np.maximum(xx - 2.0 * (sample @ c).astype(np.float64) + cc, 0.0)

    d2 = dist2(centres[0])
    if k > SEED_BATCH_FROM:
        return _seed_batched(sample, centres, d2, xx, rng)
    for i in range(1, k):
        total = d2.sum()
        pick = int(rng.choice(n, p=d2 / total)) if total > 0 else int(rng.integers(n))
        centres[i] = sample[pick]
        d2 = np.minimum(d2, dist2(centres[i]))
    return centres


def _seed_batched(sample, centres, d2, xx, rng) -> np.ndarray:
    """The rest of ``centres`` (row 0 chosen, ``d2`` its squared distances) in batches."""
    n, k = len(sample), len(centres)
    batch = -(-k // SEED_ROUNDS)
    filled = 1
    while filled < k:
        m = min(batch, k - filled)
        positive = int(np.count_nonzero(d2))
        if positive >= m:
            picks = rng.choice(n, m, replace=False, p=d2 / d2.sum())
        else:  # fewer distinct rows left than centres wanted: duplicates, as k-means++ does
            picks = rng.integers(n, size=m)
        new = sample[picks]
        centres[filled : filled + m] = new
        filled += m
        cc = np.einsum("kd,kd->k", new, new, dtype=np.float64)
        for start in range(0, n, CHUNK):
            d = xx[start : start + CHUNK, None] - 2.0 * (sample[start : start + CHUNK] @ new.T)
            d2[start : start + CHUNK] = np.minimum(
                d2[start : start + CHUNK], np.maximum((d + cc).min(axis=1), 0.0)
            )
    return centres

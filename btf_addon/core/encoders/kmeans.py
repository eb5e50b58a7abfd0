"""Deterministic k-means for the encoders: k-means++ seeding and Lloyd steps on a training
subsample, then one chunked assignment of every vector.

Everything is float32 (the data) with float64 sums where means are formed; the random choices
come from one ``numpy.random.Generator``, so a seed fixes the result.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Rows per distance block: CHUNK × k × 4 bytes stays small (k ≤ a few thousand).
CHUNK = 4096


def nearest(
    x: np.ndarray, centres: np.ndarray, scale_free: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Index of the closest centre for every row of ``x`` (N, D) among ``centres`` (K, D).

    ``scale_free``: closest after the best non-negative scale of the centre (minimises
    ‖x − s·c‖² over s ≥ 0, i.e. maximises ⟨x, c⟩₊² / ‖c‖²); returns that scale too. Otherwise
    the plain Euclidean nearest centre and a scale of 1. Returns (N,) int64, (N,) float64."""
    n = len(x)
    labels = np.zeros(n, dtype=np.int64)
    scales = np.ones(n, dtype=np.float64)
    c = centres.astype(np.float32, copy=False)
    cc = np.einsum("kd,kd->k", c, c, dtype=np.float64)
    for start in range(0, n, CHUNK):
        xs = x[start : start + CHUNK].astype(np.float32, copy=False)
        dots = (xs @ c.T).astype(np.float64)
        if scale_free:
            positive = np.maximum(dots, 0.0)
            gain = positive * positive / np.where(cc > 0, cc, np.inf)
            best = np.argmax(gain, axis=1)
            d = dots[np.arange(len(xs)), best]
            c2 = cc[best]
            scales[start : start + len(xs)] = np.divide(
                np.maximum(d, 0.0), c2, out=np.zeros(len(xs)), where=c2 > 0
            )
        else:
            best = np.argmin(cc[None, :] - 2.0 * dots, axis=1)
        labels[start : start + len(xs)] = best
    return labels, scales


def kmeans(
    x: np.ndarray,
    k: int,
    rng: np.random.Generator,
    iterations: int = 10,
    train: int = 20000,
    cancel: Callable[[], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Cluster ``x`` (N, D) float32 into at most ``k`` centres.

    Returns (centres (K', D) float32, labels (N,) int64), K' = min(k, N). Centres are trained
    on a subsample of ``train`` rows (all rows when fewer); an empty cluster is re-seeded with
    the training row farthest from its centre. ``cancel`` is called between steps (it raises
    to stop)."""
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
        labels, _ = nearest(sample, centres)
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
    labels, _ = nearest(x, centres)
    return centres, labels


def _seed(sample: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ seeding (Arthur & Vassilvitskii 2007) on ``sample``; duplicates of a chosen
    row have zero weight, so identical rows never become two centres unless nothing else is
    left."""
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
    for i in range(1, k):
        total = d2.sum()
        pick = int(rng.choice(n, p=d2 / total)) if total > 0 else int(rng.integers(n))
        centres[i] = sample[pick]
        d2 = np.minimum(d2, dist2(centres[i]))
    return centres

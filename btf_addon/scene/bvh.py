"""Bounding volume hierarchy over triangles, flattened for the OpenCL tracer.

Nodes of more than SAH_MIN triangles are split where the surface area heuristic finds the
cheapest pair of children (binned centroids, every axis: MacDonald & Booth 1990, Wald 2007), so
that a large triangle (a ground plane) is not dragged into boxes full of small ones; smaller
nodes take the median on the longest centroid axis. Leaves of ≤ LEAF_SIZE triangles, nodes in
depth-first order: an internal node's left child is the next node, its right child's index is
stored. The triangles are reordered so that every leaf owns a contiguous range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LEAF_SIZE = 4
SAH_MIN = 64  # nodes above this many triangles are split by the surface area heuristic
SAH_BINS = 16


@dataclass
class BVH:
    """bounds: (M, 6) float32 min xyz, max xyz; links: (M, 2) int32 — leaf: (first, count);
    internal: (right child, 0). order: (T,) the triangle index stored at each leaf position."""

    bounds: np.ndarray
    links: np.ndarray
    order: np.ndarray


def build_bvh(triangles: np.ndarray) -> BVH:
    """triangles: (T, 3, 3) world-space vertices (finite) → BVH."""
    tri_min = triangles.min(axis=1)
    tri_max = triangles.max(axis=1)
    centroids = triangles.mean(axis=1)
    bounds: list[np.ndarray] = []
    links: list[tuple[int, int]] = []
    order: list[np.ndarray] = []
    placed = 0
    # Explicit stack of (triangle ids, parent node whose right link to patch or -1).
    stack: list[tuple[np.ndarray, int]] = [(np.arange(len(triangles)), -1)]
    while stack:
        ids, parent = stack.pop()
        node = len(bounds)
        if parent >= 0:
            links[parent] = (node, 0)
        bounds.append(np.concatenate([tri_min[ids].min(axis=0), tri_max[ids].max(axis=0)]))
        if len(ids) <= LEAF_SIZE:
            links.append((placed, len(ids)))
            order.append(ids)
            placed += len(ids)
            continue
        c = centroids[ids]
        left = _sah_left(c, tri_min[ids], tri_max[ids]) if len(ids) > SAH_MIN else None
        if left is None:  # the median on the longest axis
            axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
            left = np.zeros(len(ids), dtype=bool)
            left[np.argpartition(c[:, axis], len(ids) // 2)[: len(ids) // 2]] = True
        links.append((-1, 0))  # the right child is patched in when created
        # Push right first so the left child is built next: it becomes node + 1.
        stack.append((ids[~left], node))
        stack.append((ids[left], -1))
    empty = np.zeros(0, dtype=np.int64)
    return BVH(
        np.array(bounds, dtype=np.float32).reshape(-1, 6),
        np.array(links, dtype=np.int32).reshape(-1, 2),
        np.concatenate(order) if order else empty,
    )


def _half_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    d = np.maximum(hi - lo, 0.0)
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]


def _sah_left(c: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
    """Which of a node's triangles (centroids c, boxes lo/hi) go left: the split between
    centroid bins that minimises area(left) · count(left) + area(right) · count(right) over
    the three axes; None when no axis can be binned or no split has a finite cost (centroids
    that coincide or lie a denormal apart: take the median)."""
    with np.errstate(over="ignore", invalid="ignore"):  # non-finite costs are refused below
        return _cheapest_split(c, lo, hi)


def _cheapest_split(c: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
    best_cost, best = np.inf, None
    c_lo, c_hi = c.min(axis=0), c.max(axis=0)
    for axis in range(3):
        scale = SAH_BINS / (c_hi[axis] - c_lo[axis]) if c_hi[axis] > c_lo[axis] else np.inf
        if not np.isfinite(scale):
            continue
        scaled = (c[:, axis] - c_lo[axis]) * scale
        bins = np.minimum(scaled, SAH_BINS - 1).astype(np.uint8)  # uint8: a radix sort below
        count = np.bincount(bins, minlength=SAH_BINS)
        # Each bin's box: the triangles sorted by bin, reduced per run (ufunc.at is 5x slower).
        order = np.argsort(bins, kind="stable")
        ranked = bins[order]
        starts = np.flatnonzero(np.r_[True, ranked[1:] != ranked[:-1]])
        b_lo = np.full((SAH_BINS, 3), np.inf)
        b_hi = np.full((SAH_BINS, 3), -np.inf)
        b_lo[ranked[starts]] = np.minimum.reduceat(lo[order], starts, axis=0)
        b_hi[ranked[starts]] = np.maximum.reduceat(hi[order], starts, axis=0)
        # split k: bins [0, k] left, (k, SAH_BINS) right
        left_area = _half_area(np.minimum.accumulate(b_lo), np.maximum.accumulate(b_hi))
        right_lo = np.minimum.accumulate(b_lo[::-1])[::-1]
        right_hi = np.maximum.accumulate(b_hi[::-1])[::-1]
        right_area = _half_area(right_lo, right_hi)
        n_left = np.cumsum(count)[:-1]
        n_right = len(c) - n_left
        cost = left_area[:-1] * n_left + right_area[1:] * n_right  # empty sides: inf · 0
        cost[(n_left == 0) | (n_right == 0) | ~np.isfinite(cost)] = np.inf
        k = int(np.argmin(cost))
        if cost[k] < best_cost:
            best_cost, best = cost[k], bins <= k
    return best

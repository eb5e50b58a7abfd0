"""Bounding volume hierarchy over triangles, flattened for the OpenCL tracer.

Median split on the longest centroid axis, leaves of ≤ LEAF_SIZE triangles, nodes in depth-first
order: an internal node's left child is the next node, its right child's index is stored. The
triangles are reordered so that every leaf owns a contiguous range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LEAF_SIZE = 4


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
        axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
        half = len(ids) // 2
        split = np.argpartition(c[:, axis], half)
        links.append((-1, 0))  # patched when the right child is created
        # Push right first so the left child is built next: it becomes node + 1.
        stack.append((ids[split[half:]], node))
        stack.append((ids[split[:half]], -1))
    empty = np.zeros(0, dtype=np.int64)
    return BVH(
        np.array(bounds, dtype=np.float32).reshape(-1, 6),
        np.array(links, dtype=np.int32).reshape(-1, 2),
        np.concatenate(order) if order else empty,
    )

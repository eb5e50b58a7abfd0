"""The flattened BVH (btf_addon/scene/bvh.py): its layout's invariants, and closest hits found
through it equal to testing every triangle (an independent brute force in numpy)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from btf_addon.scene import bvh
from btf_addon.scene.bvh import LEAF_SIZE, build_bvh


def _ground_and_blobs(rng, n_small: int) -> np.ndarray:
    """One large ground (two triangles) under many small triangles: the case where the
    surface area heuristic and the median split disagree."""
    ground = np.array(
        [[[-50, -50, 0], [50, -50, 0], [50, 50, 0]], [[-50, -50, 0], [50, 50, 0], [-50, 50, 0]]],
        dtype=np.float64,
    )
    centres = rng.uniform([-2, -2, 0.5], [2, 2, 3], size=(n_small, 1, 3))
    small = centres + rng.normal(scale=0.05, size=(n_small, 3, 3))
    return np.concatenate([ground, small])


def _leaves(tree):
    return [(i, f, c) for i, (f, c) in enumerate(tree.links) if c > 0]


def _check_layout(tree, triangles):
    # Every triangle sits in exactly one leaf; leaves own contiguous, disjoint ranges.
    assert sorted(tree.order.tolist()) == list(range(len(triangles)))
    covered = np.zeros(len(triangles), dtype=int)
    for node, first, count in _leaves(tree):
        assert 1 <= count <= LEAF_SIZE
        covered[first : first + count] += 1
        tris = triangles[tree.order[first : first + count]]
        lo, hi = tree.bounds[node, :3], tree.bounds[node, 3:]
        assert np.all(tris.min(axis=(0, 1)) >= lo - 1e-6) and np.all(
            tris.max(axis=(0, 1)) <= hi + 1e-6
        )
    assert np.all(covered == 1)
    # An internal node's children: node + 1 and the stored right index, boxes inside its own.
    for node, (right, count) in enumerate(tree.links):
        if count == 0:
            assert node + 1 < right < len(tree.links)
            for child in (node + 1, right):
                assert np.all(tree.bounds[child, :3] >= tree.bounds[node, :3])
                assert np.all(tree.bounds[child, 3:] <= tree.bounds[node, 3:])


def _closest_brute(o, d, triangles):
    """Möller–Trumbore against every triangle, in float64."""
    v0, v1, v2 = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - v0
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
    ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    t = np.where(ok, t, np.inf)
    return int(np.argmin(t)) if np.isfinite(t.min()) else -1, float(t.min())


def _closest_through_tree(o, d, tree, triangles):
    """The kernel's traversal (kernels/include/btf_trace.h) written in numpy: boxes first."""
    inv_d = 1.0 / np.where(d == 0, 1e-30, d)
    best, hit, stack = np.inf, -1, [0]
    while stack:
        node = stack.pop()
        t0 = (tree.bounds[node, :3] - o) * inv_d
        t1 = (tree.bounds[node, 3:] - o) * inv_d
        enter = max(np.minimum(t0, t1).max(), 0.0)
        if enter > min(np.maximum(t0, t1).min(), best):
            continue
        first, count = tree.links[node]
        if count > 0:
            ids = tree.order[first : first + count]
            i, t = _closest_brute(o, d, triangles[ids])
            if i >= 0 and t < best:
                best, hit = t, int(ids[i])
        else:
            stack += [first, node + 1]
    return hit, best


@pytest.mark.parametrize("sah_min", [64, 10**9], ids=["SAH", "median only"])
def test_layout_and_hits_equal_brute_force(monkeypatch, sah_min):
    monkeypatch.setattr(bvh, "SAH_MIN", sah_min)
    rng = np.random.default_rng(5)
    triangles = _ground_and_blobs(rng, 600)
    tree = build_bvh(triangles)
    _check_layout(tree, triangles)
    hits = 0
    for _ in range(300):
        o = rng.uniform([-3, -3, 4], [3, 3, 6])
        d = rng.normal(size=3) + np.array([0.0, 0.0, -2.0])
        d /= np.linalg.norm(d)
        expected, t_expected = _closest_brute(o, d, triangles)
        got, t_got = _closest_through_tree(o, d, tree, triangles)
        assert got == expected or np.isclose(t_got, t_expected, rtol=1e-9)
        hits += expected >= 0
    assert hits > 250  # the rays aim at the scene: the check is not vacuous


def test_sah_keeps_the_ground_out_of_the_small_triangles_boxes():
    """The reason for the heuristic: with the median split the ground's huge box is merged
    into half the tree, so every ray visits boxes full of small triangles it cannot hit."""
    triangles = _ground_and_blobs(np.random.default_rng(6), 2000)
    tree = build_bvh(triangles)
    ground_leaf = [
        node
        for node, first, count in _leaves(tree)
        if {0, 1} & set(tree.order[first : first + count].tolist())
    ]
    # The ground's leaves are reached from the root within a few levels (depth ≤ 3), not at
    # the bottom of a median-split subtree (depth ≈ log2(2000 / 4) ≈ 9).
    depth = {0: 0}
    for node, (right, count) in enumerate(tree.links):
        if count == 0:
            depth[node + 1] = depth[right] = depth[node] + 1
    assert max(depth[n] for n in ground_leaf) <= 3


def test_degenerate_and_single_triangles():
    flat = np.zeros((70, 3, 3))  # every triangle a point at the origin: no axis has extent
    tree = build_bvh(flat)
    _check_layout(tree, flat)
    one = build_bvh(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], dtype=np.float64))
    assert one.links.tolist() == [[0, 1]] and one.order.tolist() == [0]


@pytest.mark.parametrize(
    "extreme",
    ["denormal extent", "huge coordinates"],
)
def test_extreme_coordinates_build_without_warnings(extreme):
    """Centroids a denormal apart (the bin scale overflows: the heuristic steps aside for the
    median) and coordinates near float32's limit (the largest the flattened boxes store):
    built without a warning."""
    triangles = np.zeros((100, 3, 3))
    if extreme == "denormal extent":
        triangles[::2, :, 0] = 5e-324
    else:
        triangles[:, :, 0] = np.linspace(0.0, 3e38, 100)[:, None]
        triangles[:, 1, 1] = 3e38
        triangles = triangles.astype(np.float32).astype(np.float64)  # as exported: float32
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tree = build_bvh(triangles)
    _check_layout(tree, triangles)


def _median_reference(triangles: np.ndarray):
    """An independent median builder, one node at a time (what the batched median subtrees
    replaced): depth-first nodes as (box, leaf triangle set or None), the left child taking
    the n // 2 lowest centroids on the longest centroid axis."""
    centroids = triangles.mean(axis=1)
    nodes = []

    def visit(ids):
        box = np.concatenate([triangles[ids].min(axis=(0, 1)), triangles[ids].max(axis=(0, 1))])
        if len(ids) <= LEAF_SIZE:
            nodes.append((box, frozenset(ids.tolist())))
            return
        nodes.append((box, None))
        c = centroids[ids]
        axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
        ranked = ids[np.argsort(c[:, axis], kind="stable")]
        visit(ranked[: len(ids) // 2])
        visit(ranked[len(ids) // 2 :])

    visit(np.arange(len(triangles)))
    return nodes


@pytest.mark.parametrize("n", [1, 5, 9, 63, 64, 65, 1000])
def test_batched_median_subtrees_equal_a_node_by_node_build(monkeypatch, n):
    """Without the heuristic every node is a median node, all built in batches a level at a
    time: the same nodes, boxes and leaves as the one-node-at-a-time reference (random
    triangles: no two centroids tie on an axis, so the partition is unique)."""
    monkeypatch.setattr(bvh, "SAH_MIN", 10**9)
    triangles = np.random.default_rng(n).normal(size=(n, 3, 3))
    tree = build_bvh(triangles)
    _check_layout(tree, triangles)
    reference = _median_reference(triangles)
    assert len(tree.links) == len(reference)
    for node, (box, leaf) in enumerate(reference):
        np.testing.assert_array_equal(tree.bounds[node], box.astype(np.float32))
        first, count = tree.links[node]
        if leaf is None:
            assert count == 0
        else:
            assert frozenset(tree.order[first : first + count].tolist()) == leaf

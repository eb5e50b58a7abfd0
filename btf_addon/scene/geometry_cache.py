"""BVHs and convexity verdicts kept on disk between sessions, as compiled kernels and
importance tables are: both are functions of the scene's world-space triangles alone, and
building them was a fifth of a small scene's F12 (a 4k-triangle sphere: BVH 27 ms, convexity
16 ms of ~230 ms), paid again by every new Blender process (a render farm's every frame, an
F12 after a material tweak).

Key: BLAKE2b of the triangles in a canonical form (Blender's triangle order differs from one
process to the next: the BVH's key is its triangles' boxes sorted by a hash of their bits, the
verdict's the triangles sorted the same way, each from its corner of smallest hash), what is
stored (``bvh``, or ``convex`` and its tolerance) and the source text of bvh.py or analysis.py
(a changed build makes new keys; old files are no longer read and age out). Files:
core/npz_store.py (the zip's CRC-32 checked on every read); a file that fails to read or is
not a valid BVH for the triangle count (links in range, the order a permutation) is rebuilt
and replaced: a damaged file can cost time, never a wrong image.

Meshes below MIN_TRIANGLES are built each time (a file read costs about what the build
does). Size: a BVH takes ~27 B per triangle (1M triangles: ~27 MB); when a store takes the
folder past its cap (512 MiB, ``STORE.cap_bytes``) the files used longest ago are removed
first, so the folder stays under the cap whatever is rendered.

Where: ``STORE.set_folder`` (Blender: the extension's user directory, removed with it), else
``BTF_GEOMETRY_CACHE``, else ``$XDG_CACHE_HOME/btf_materials/geometry``.
``BTF_GEOMETRY_CACHE=off`` turns it off. A folder that cannot be written is logged once and
the data built each time, as without a cache. Writes are atomic (core/fileio.py).
"""

from __future__ import annotations

import sys
from collections.abc import Callable

import numpy as np

from ..core.npz_store import NpzStore
from ..core.sampling.table_cache import table_key
from . import bvh as bvh_module

#: Below this many triangles a build is about as fast as reading a file.
MIN_TRIANGLES = 512
#: The files (core/npz_store.py): at most 512 MiB, least recently used first out.
STORE = NpzStore("geometry cache", "BTF_GEOMETRY_CACHE", "geometry", 512 * 2**20)


def cached_bvh(triangles: np.ndarray) -> bvh_module.BVH:
    """A BVH over ``triangles`` (T, 3, 3), from the disk when a mesh with the same triangle
    boxes was built before, in any order (Blender's triangle order is not the same from one
    process to the next). Stored BVHs are over the boxes in a canonical order; the one
    returned is mapped to ``triangles``' order. Any order gives a valid tree: a BVH needs
    only each triangle's box (the centroids steer its quality, not its correctness)."""
    count = len(triangles)
    if count < MIN_TRIANGLES:
        return bvh_module.build_bvh(triangles)
    triangles = np.asarray(triangles, dtype=np.float32)
    boxes = np.concatenate([triangles.min(axis=1), triangles.max(axis=1)], axis=1)
    canonical = _canonical_order(boxes)
    key = table_key([boxes[canonical]], {"what": "bvh"}, [bvh_module])
    arrays = STORE.load(key, lambda a: _valid_bvh(a, count))
    if arrays is None:
        built = bvh_module.build_bvh(triangles[canonical])
        arrays = {"bounds": built.bounds, "links": built.links, "order": built.order}
        STORE.store(key, arrays)
    return bvh_module.BVH(arrays["bounds"], arrays["links"], canonical[arrays["order"]])


def cached_verdict(corners: np.ndarray, what: dict, decide: Callable[[], bool]) -> bool:
    """``decide()`` for the triangles of ``corners`` (3·T, ≥ 3) (analysis.py's convexity),
    from the disk when known for the same triangles in any order, each with its corners in any
    cyclic order (the same orientation); ``what`` names the question and its parameters."""
    if len(corners) < 3 * MIN_TRIANGLES:
        return decide()
    key = table_key([_canonical_triangles(corners)], what, [sys.modules[decide.__module__]])
    arrays = STORE.load(key, lambda a: a.get("verdict", np.zeros(0)).shape == (1,))
    if arrays is not None:
        return bool(arrays["verdict"][0])
    verdict = bool(decide())
    STORE.store(key, {"verdict": np.array([verdict])})
    return verdict


def _row_hashes(rows: np.ndarray) -> np.ndarray:
    """(N, k) float32 → (N,) uint64, a hash of each row's bits (FNV-1a over 32-bit words)."""
    words = np.ascontiguousarray(rows, dtype=np.float32).view(np.uint32).astype(np.uint64)
    hashes = np.full(len(rows), 0xCBF29CE484222325, dtype=np.uint64)
    for column in words.T:
        hashes = (hashes ^ column) * np.uint64(0x100000001B3)  # wraps modulo 2⁶⁴
    return hashes


def _canonical_order(rows: np.ndarray) -> np.ndarray:
    """A permutation that puts the same multiset of rows in the same order whatever order
    they come in (by hash; rows equal in every bit are interchangeable, and a rare collision
    between different rows only costs a miss: the key is computed from the rows in this
    order)."""
    return np.argsort(_row_hashes(rows), kind="stable")


def _canonical_triangles(corners: np.ndarray) -> np.ndarray:
    """(3·T, ≥ 3) corners → (T, 9) float32 triangles, each rotated to start at its corner of
    smallest hash (the winding, i.e. the face's side, kept), in canonical order."""
    points = np.ascontiguousarray(corners[:, :3], dtype=np.float32)
    start = _row_hashes(points).reshape(-1, 3).argmin(axis=1)
    rolled = (start[:, None] + np.arange(3)) % 3 + 3 * np.arange(len(start))[:, None]
    triangles = points[rolled.ravel()].reshape(-1, 9)
    return triangles[_canonical_order(triangles)]


def _valid_bvh(arrays: dict, count: int) -> bool:
    """The arrays form a BVH over ``count`` triangles that the tracer can walk without
    reading outside its buffers."""
    bounds, links, order = (arrays.get(k) for k in ("bounds", "links", "order"))
    if bounds is None or links is None or order is None:
        return False
    nodes = len(links)
    if bounds.shape != (nodes, 6) or links.shape != (nodes, 2) or order.shape != (count,):
        return False
    if bounds.dtype != np.float32 or links.dtype != np.int32 or not np.isfinite(bounds).all():
        return False
    if nodes == 0 or order.min() < 0 or order.max() >= count:
        return False
    if not (np.bincount(order, minlength=count) == 1).all():  # a permutation
        return False
    leaf = links[:, 1] > 0
    first, size = links[leaf, 0].astype(np.int64), links[leaf, 1].astype(np.int64)
    right = links[~leaf, 0]
    inner = np.flatnonzero(~leaf)
    return bool(
        (first >= 0).all()
        and (first + size <= count).all()
        and (links[~leaf, 1] == 0).all()
        and (right > inner).all()
        and (right < nodes).all()
    )

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
``<key>.npz`` (uncompressed: a read is a copy), holding the arrays and a digest of them. A
file that fails to read, does not match its digest or is not a valid BVH for the triangle
count (links in range, the order a permutation) is rebuilt and replaced: a damaged file can
cost time, never a wrong image.

Meshes below MIN_TRIANGLES are built each time (a file read costs about what the build
does). Size: a BVH takes ~27 B per triangle (1M triangles: ~27 MB); when a store takes the
folder past CAP_BYTES the files used longest ago are removed first, so the folder stays under
the cap whatever is rendered.

Where: ``set_cache_dir`` (Blender: the extension's user directory, removed with it), else
``BTF_GEOMETRY_CACHE``, else ``$XDG_CACHE_HOME/btf_materials/geometry``.
``BTF_GEOMETRY_CACHE=off`` turns it off. A folder that cannot be written is logged once and
the data built each time, as without a cache. Writes are atomic (core/fileio.py).
"""

from __future__ import annotations

import hashlib
import logging
import os
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..core.fileio import atomic_write, user_cache_root
from ..core.sampling.table_cache import table_key
from . import bvh as bvh_module

log = logging.getLogger(__name__)

OFF = "off"
#: Below this many triangles a build is about as fast as reading a file.
MIN_TRIANGLES = 512
#: The folder's most bytes after a store (least recently used files go first).
CAP_BYTES = 512 * 2**20
_cache_dir_setting: Path | None = None
_warned: set[str] = set()
stats = {"disk_hits": 0, "stored": 0, "rejected": 0, "evicted": 0}


def set_cache_dir(path: str | Path | None) -> None:
    """Keep BVHs and verdicts in ``path`` (None: back to the default, module docstring)."""
    global _cache_dir_setting
    _cache_dir_setting = Path(path) if path is not None else None


def cache_dir() -> Path | None:
    """The folder in use, None when the cache is off."""
    if _cache_dir_setting is not None:
        return _cache_dir_setting
    env = os.environ.get("BTF_GEOMETRY_CACHE")
    if env:
        return None if env.strip().lower() == OFF else Path(env)
    return user_cache_root() / "btf_materials" / "geometry"


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
    arrays = _load(key, lambda a: _valid_bvh(a, count))
    if arrays is None:
        built = bvh_module.build_bvh(triangles[canonical])
        arrays = {"bounds": built.bounds, "links": built.links, "order": built.order}
        _store(key, arrays)
    return bvh_module.BVH(arrays["bounds"], arrays["links"], canonical[arrays["order"]])


def cached_verdict(corners: np.ndarray, what: dict, decide: Callable[[], bool]) -> bool:
    """``decide()`` for the triangles of ``corners`` (3·T, ≥ 3) (analysis.py's convexity),
    from the disk when known for the same triangles in any order, each with its corners in any
    cyclic order (the same orientation); ``what`` names the question and its parameters."""
    if len(corners) < 3 * MIN_TRIANGLES:
        return decide()
    key = table_key([_canonical_triangles(corners)], what, [sys.modules[decide.__module__]])
    arrays = _load(key, lambda a: a.get("verdict", np.zeros(0)).shape == (1,))
    if arrays is not None:
        return bool(arrays["verdict"][0])
    verdict = bool(decide())
    _store(key, {"verdict": np.array([verdict])})
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


def _digest(arrays: dict) -> np.ndarray:
    digest = hashlib.blake2b(digest_size=16)
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}{array.dtype.str}{array.shape}".encode())
        digest.update(memoryview(array).cast("B"))
    return np.frombuffer(digest.digest(), dtype=np.uint8)


def _load(key: str, valid: Callable[[dict], bool]) -> dict | None:
    folder = cache_dir()
    if folder is None:
        return None
    path = folder / f"{key}.npz"
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        return _reject(path, f"unreadable ({exc})")
    stored = arrays.pop("digest", None)
    if stored is None or not np.array_equal(stored, _digest(arrays)):
        return _reject(path, "does not match its digest")
    if not valid(arrays):
        return _reject(path, "holds no valid data for this mesh")
    try:
        os.utime(path)  # recently used: the last to be evicted
    except OSError:
        pass
    stats["disk_hits"] += 1
    return arrays


def _reject(path: Path, why: str) -> None:
    stats["rejected"] += 1
    log.warning("geometry cache: %s %s; building it again", path.name, why)
    return None


def _store(key: str, arrays: dict) -> None:
    """Keep ``arrays`` under ``key`` (failures logged once per folder, never raised: the
    cache only saves time), then keep the folder under CAP_BYTES."""
    folder = cache_dir()
    if folder is None:
        return
    payload = {**arrays, "digest": _digest(arrays)}
    try:
        atomic_write(folder / f"{key}.npz", lambda fh: np.savez(fh, **payload))
        stats["stored"] += 1
        _evict(folder, keep=f"{key}.npz")
    except OSError as exc:
        if str(folder) not in _warned:
            _warned.add(str(folder))
            log.warning(
                "geometry cache: cannot write in %s (%s); BVHs are built each session (set "
                "BTF_GEOMETRY_CACHE to a writable folder, or 'off')",
                folder,
                exc.strerror or exc,
            )


def _evict(folder: Path, keep: str) -> None:
    """Remove the least recently used files until the folder holds at most CAP_BYTES."""
    entries = []
    for path in folder.glob("*.npz"):
        try:
            info = path.stat()
        except OSError:
            continue  # removed by another process meanwhile
        entries.append((info.st_mtime, info.st_size, path))
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries, key=lambda e: e[0]):
        if total <= CAP_BYTES:
            break
        if path.name == keep:
            continue
        try:
            path.unlink()
            stats["evicted"] += 1
        except OSError:
            pass  # another process's eviction got there first
        total -= size

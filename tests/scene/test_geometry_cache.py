"""BVHs and convexity verdicts on disk between sessions (scene/geometry_cache.py): a second
request for the same triangles reads what the first stored, equal to a fresh build; other
triangles, other keys; a damaged or forged file is rebuilt and replaced, never used; the folder
stays under its cap, least recently used first; an unwritable folder or the cache turned off
only costs the build."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from btf_addon.scene import analysis, geometry_cache
from btf_addon.scene.primitives import uv_sphere


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "geometry"
    geometry_cache.STORE.set_folder(folder)
    monkeypatch.setattr(geometry_cache.STORE, "stats", dict.fromkeys(geometry_cache.STORE.stats, 0))
    yield folder
    geometry_cache.STORE.set_folder(None)


def sphere_triangles(segments=48, rings=24, shift=0.0) -> np.ndarray:
    corners = uv_sphere(1.0, segments, rings).world_space_corners()
    return corners[:, :3].reshape(-1, 3, 3) + np.float32(shift)


def encloses(bvh, triangles) -> bool:
    """Every leaf's triangles inside its box (what the tracer relies on), each triangle once."""
    if sorted(bvh.order.tolist()) != list(range(len(triangles))):
        return False
    ordered = triangles[bvh.order]
    for box, (first, count) in zip(bvh.bounds, bvh.links, strict=True):
        if count > 0:
            inside = ordered[first : first + count].reshape(-1, 3)
            if (inside < box[:3]).any() or (inside > box[3:]).any():
                return False
    return True


def same_bvh(a, b) -> bool:
    return all(
        np.array_equal(x, y)
        for x, y in zip((a.bounds, a.links, a.order), (b.bounds, b.links, b.order), strict=True)
    )


def test_the_second_request_reads_the_stored_bvh(cache):
    triangles = sphere_triangles()
    assert len(triangles) >= geometry_cache.MIN_TRIANGLES
    first = geometry_cache.cached_bvh(triangles)
    assert geometry_cache.STORE.stats == {"disk_hits": 0, "stored": 1, "rejected": 0, "evicted": 0}
    second = geometry_cache.cached_bvh(triangles.copy())
    assert geometry_cache.STORE.stats["disk_hits"] == 1
    assert same_bvh(second, first) and encloses(first, triangles)
    # Blender's triangle order changes between processes, and a triangle's first corner may
    # too: still a hit, mapped to this order
    rng = np.random.default_rng(1)
    shuffled = np.roll(triangles[rng.permutation(len(triangles))], 1, axis=1)
    third = geometry_cache.cached_bvh(shuffled)
    assert geometry_cache.STORE.stats["disk_hits"] == 2 and encloses(third, shuffled)
    moved = sphere_triangles(shift=0.5)  # other triangles
    assert encloses(geometry_cache.cached_bvh(moved), moved)
    assert geometry_cache.STORE.stats["stored"] == 2


def test_small_meshes_are_built_each_time(cache):
    triangles = sphere_triangles(8, 4)
    assert len(triangles) < geometry_cache.MIN_TRIANGLES
    geometry_cache.cached_bvh(triangles)
    assert geometry_cache.STORE.stats["stored"] == 0 and not cache.exists()


def _rewrite(path, change):
    """Replace the stored arrays with ``change(arrays)``, in a sound file."""
    with np.load(path) as data:
        arrays = {name: data[name].copy() for name in data.files}
    change(arrays)
    np.savez(path, **arrays)


def _forge(arrays):
    """A damaged tree in a sound file: a right child past the last node."""
    inner = np.flatnonzero(arrays["links"][:, 1] == 0)[0]
    arrays["links"][inner, 0] = len(arrays["links"]) + 7


def _flip_a_byte(path):
    """A changed byte inside the arrays (what a disk or a copy can do): the zip's CRC-32."""
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(
    "damage",
    [
        lambda path: path.write_bytes(path.read_bytes()[:100]),  # truncated
        lambda path: path.write_bytes(b"not a zip at all"),
        _flip_a_byte,
        lambda path: _rewrite(path, _forge),
        lambda path: _rewrite(path, lambda a: a.pop("order")),
    ],
    ids=["truncated", "garbage", "changed", "forged", "incomplete"],
)
def test_a_damaged_file_is_rebuilt_and_replaced(cache, caplog, damage):
    triangles = sphere_triangles()
    fresh = geometry_cache.cached_bvh(triangles)
    (path,) = cache.glob("*.npz")
    damage(path)
    with caplog.at_level(logging.WARNING):
        again = geometry_cache.cached_bvh(triangles)
    assert same_bvh(again, fresh) and encloses(again, triangles)
    assert geometry_cache.STORE.stats["rejected"] == 1 and "building it again" in caplog.text
    assert same_bvh(geometry_cache.cached_bvh(triangles), fresh)  # the replacement reads
    assert geometry_cache.STORE.stats["disk_hits"] == 1


def test_the_folder_stays_under_its_cap(cache, monkeypatch):
    geometry_cache.cached_bvh(sphere_triangles())
    (path,) = cache.glob("*.npz")
    size = path.stat().st_size
    monkeypatch.setattr(geometry_cache.STORE, "cap_bytes", int(2.5 * size))
    for shift in (1.0, 2.0, 3.0, 4.0):
        geometry_cache.cached_bvh(sphere_triangles(shift=shift))
    files = list(cache.glob("*.npz"))
    assert sum(f.stat().st_size for f in files) <= 2.5 * size and len(files) == 2
    assert not path.exists()  # the first file was used longest ago
    assert geometry_cache.STORE.stats["evicted"] == 3
    last = geometry_cache.cached_bvh(sphere_triangles(shift=4.0))
    assert geometry_cache.STORE.stats["disk_hits"] == 1 and len(last.order) > 0


def test_convexity_verdicts_are_kept_per_mesh_and_question(cache):
    ball = uv_sphere(1.0, 48, 24).world_space_corners()
    dented = ball.copy()
    dented[:, :3][np.abs(dented[:, 0] - 1.0) < 1e-3] *= 0.5  # the vertices at +X pushed in
    assert analysis._convex(ball) and not analysis._convex(dented)
    assert geometry_cache.STORE.stats["stored"] == 2
    assert analysis._convex(ball) and not analysis._convex(dented)
    assert geometry_cache.STORE.stats["disk_hits"] == 2
    # in another triangle order, each triangle from another corner: the same mesh
    triangles = ball.reshape(-1, 3, ball.shape[1])
    reordered = np.roll(triangles[::-1], 2, axis=1).reshape(ball.shape)
    assert analysis._convex(reordered) and geometry_cache.STORE.stats["disk_hits"] == 3
    # every triangle turned over (its corners reversed): another mesh, judged anew
    flipped = triangles[:, ::-1].reshape(ball.shape)
    assert not analysis._convex(flipped) and geometry_cache.STORE.stats["stored"] == 3
    calls = []
    assert not geometry_cache.cached_verdict(ball, {"what": "other"}, lambda: calls.append(1))
    assert (
        calls == [1] and geometry_cache.STORE.stats["stored"] == 4
    )  # another question, another key


def test_unwritable_folder_or_off_only_costs_the_build(tmp_path, monkeypatch, caplog):
    blocked = tmp_path / "file"
    blocked.write_text("a file where the folder should be")
    geometry_cache.STORE.set_folder(blocked / "geometry")
    try:
        with caplog.at_level(logging.WARNING):
            for _ in range(2):
                assert encloses(geometry_cache.cached_bvh(sphere_triangles()), sphere_triangles())
        assert caplog.text.count("cannot write") == 1
    finally:
        geometry_cache.STORE.set_folder(None)
    monkeypatch.setenv("BTF_GEOMETRY_CACHE", "off")
    assert geometry_cache.STORE.folder() is None
    monkeypatch.setenv("BTF_GEOMETRY_CACHE", str(tmp_path / "elsewhere"))
    assert geometry_cache.STORE.folder() == tmp_path / "elsewhere"

"""The light bake as a file (btf_addon/render/light_bake.py): written whole, read back bit for
bit, damaged files refused with a message that says to bake again, and which bakes a change
makes stale. No Blender, no OpenCL: bakes built by hand from small arrays."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from btf_addon.render import light_bake
from btf_addon.render.light_bake import (
    FORMAT_VERSION,
    GRID_ARRAYS,
    VALUE_ARRAYS,
    LightBake,
    LightBakeError,
    MeshBake,
    load,
)

KNOBS = {
    "spacing": 0.25,
    "view_bins": 2,
    "samples": 32,
    "footprint": 16,
    "bounces": 4,
    "clamp_indirect": 10.0,
    "seed": 7,
}


def _arrays(rng: np.random.Generator, points: int = 6, bins: int = 4) -> dict[str, np.ndarray]:
    """A grid's arrays of ``points`` points over two triangles, a (P, bins, 3) ratio of
    arbitrary float32 values (every bit of them must survive the round trip) and unit light
    directions."""
    normals = rng.normal(size=(points, 3)).astype(np.float32)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return {
        "positions": rng.normal(size=(points, 3)).astype(np.float32),
        "normals": normals,
        "tri_cuts": np.array([1, 1], np.int32),
        "tri_first": np.array([0, 3], np.int32),
        "tri_points": np.array([0, 1, 2, 3, 4, 5], np.int32),
        "point_mesh": np.array([0, 0, 0, 1, 1, 1], np.int32)[:points],
        # _meshes(): Ground triangle 0, Ball triangle 1, Lamp post and Moon none
        "mesh_first_triangle": np.array([0, 1, 2, 2, 2], np.int32),
        "ratio": rng.random((points, bins, 3)).astype(np.float32),
        "light_dir": normals.copy(),
    }


def _meshes() -> list[MeshBake]:
    return [
        MeshBake(
            "Ground",
            "d-ground",
            baked=True,
            shadows=True,
            interreflection=True,
            reason="'Ball' and it face each other: shadows and interreflection",
            neighbours=["Ball"],
            points=3,
            seconds=0.5,
        ),
        MeshBake(
            "Ball",
            "d-ball",
            baked=True,
            shadows=True,
            interreflection=True,
            reason="'Ground' and it face each other: shadows and interreflection",
            neighbours=["Ground"],
            points=3,
            seconds=1.25,
        ),
        MeshBake(
            "Lamp post",
            "d-post",
            baked=True,
            shadows=False,
            interreflection=True,
            reason="non-convex: folds shadow and reflect onto itself",
            points=0,
        ),
        MeshBake(
            "Moon",
            "d-moon",
            baked=False,
            shadows=False,
            interreflection=False,
            reason="alone and convex: nothing to bake",
        ),
    ]


def _bake(rng: np.random.Generator, **changes) -> LightBake:
    fields = {
        "arrays": _arrays(rng),
        "knobs": dict(KNOBS),
        "meshes": _meshes(),
        "scene_digest": "scene-1",
        "seconds": 1.75,
    }
    fields.update(changes)
    return LightBake(**fields)


def test_mesh_triangles_finds_a_baked_mesh_by_name_and_nothing_else(rng):
    bake = _bake(rng)
    assert bake.mesh_triangles("Ground") == (0, 1)
    assert bake.mesh_triangles("Ball") == (1, 2)
    assert bake.mesh_triangles("Lamp post") == (2, 2)  # baked, but no triangles
    assert bake.mesh_triangles("Moon") is None  # not baked: drawn with live light
    assert bake.mesh_triangles("Sun") is None  # not in the bake


def _digests(bake: LightBake) -> dict[str, str]:
    return {m.name: m.digest for m in bake.meshes}


def _write_npz(path: Path, meta: dict, arrays: dict[str, np.ndarray]) -> None:
    """A file as the format lays it out, with any meta (to forge other versions)."""
    with open(path, "wb") as f:
        np.savez(f, meta=np.frombuffer(json.dumps(meta).encode(), np.uint8), **arrays)


def _temporaries(folder: Path) -> list[Path]:
    """core/fileio.py's temporaries: ``.<stem>.pid<PID>-<host>.<random>.tmp<suffix>``."""
    return [p for p in folder.iterdir() if p.name.startswith(".") or ".tmp" in p.name]


# --- round trip --------------------------------------------------------------------------------


def test_save_then_load_gives_the_same_bake(tmp_path, rng):
    bake = _bake(rng)
    path = tmp_path / "scene.Scene.light_bake.npz"
    assert bake.save(path) == path
    back = load(path)
    assert set(back.arrays) == set(GRID_ARRAYS) | set(VALUE_ARRAYS) == set(bake.arrays)
    for name, array in bake.arrays.items():
        got = back.arrays[name]
        assert got.dtype == array.dtype and got.shape == array.shape, name
        assert got.tobytes() == array.tobytes(), name  # bit for bit
    assert back.knobs == bake.knobs
    assert back.meshes == bake.meshes
    assert back.scene_digest == bake.scene_digest
    assert back.seconds == bake.seconds
    assert back.view_bins == 2 and back.nbytes == bake.nbytes
    assert back.report() == bake.report()
    assert _temporaries(tmp_path) == []


def test_a_bake_with_no_points_round_trips(tmp_path, rng):
    """A scene where nothing needed baking still writes a file that reads back."""
    arrays = {k: v[:0] for k, v in _arrays(rng).items()}
    bake = _bake(rng, arrays=arrays, meshes=[_meshes()[3]])
    back = load(bake.save(tmp_path / "empty.light_bake.npz"))
    assert back.arrays["ratio"].shape == (0, 4, 3) and back.meshes == bake.meshes


# --- written whole -----------------------------------------------------------------------------


def _savez_failing_half_way(real_savez):
    def savez(f, **arrays):
        real_savez(f, **arrays)  # the whole file's bytes, then fail before it is complete
        f.truncate(f.tell() // 2)
        raise OSError(28, "No space left on device")

    return savez


# np.savez leaves its ZipFile open when a write fails; the ZipFile's __del__ later finds its
# file (the temporary) closed and removed: harmless, reported as "Exception ignored".
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.parametrize("failure", ["savez fails half-way", "an unsavable array"])
def test_a_failed_save_leaves_the_old_file_intact(tmp_path, rng, monkeypatch, failure):
    path = tmp_path / "scene.Scene.light_bake.npz"
    old = _bake(rng)
    old.save(path)
    before = path.read_bytes()
    new = _bake(rng, scene_digest="scene-2")
    if failure == "savez fails half-way":
        monkeypatch.setattr(np, "savez", _savez_failing_half_way(np.savez))
        expected = OSError
    else:
        # Meta and the first arrays are written before this one fails to pickle.
        new.arrays["zzz"] = np.array(lambda: None, dtype=object)
        expected = Exception
    with pytest.raises(expected):
        new.save(path)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert load(path).scene_digest == "scene-1"
    assert _temporaries(tmp_path) == [], "a temporary was left beside the bake"
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


# --- damaged files -----------------------------------------------------------------------------


def _assert_refused(path: Path) -> LightBakeError:
    with pytest.raises(LightBakeError) as info:
        load(path)
    message = str(info.value)
    assert "bake again" in message and str(path) in message, message
    return info.value


def _damage(kind: str, good: bytes, ratio: np.ndarray) -> bytes:
    if kind == "truncated to half":
        return good[: len(good) // 2]
    if kind == "truncated by 10 bytes":
        return good[:-10]
    if kind == "a flipped byte in the middle":
        # In the middle of the values (the file's own middle may be a byte the zip does not
        # check, a timestamp: test_every_flipped_byte_is_refused_or_harmless covers those).
        start = good.find(ratio.tobytes())
        assert start > 0
        middle = start + ratio.nbytes // 2
        return good[:middle] + bytes([good[middle] ^ 0xFF]) + good[middle + 1 :]
    if kind == "not a zip file":
        return b"this is not a light bake\n" * 20
    if kind == "empty":
        return b""
    raise AssertionError(kind)


@pytest.mark.parametrize(
    "kind",
    [
        "truncated to half",
        "truncated by 10 bytes",
        "a flipped byte in the middle",
        "not a zip file",
        "empty",
    ],
)
def test_damaged_files_are_refused(tmp_path, rng, kind):
    path = tmp_path / "scene.Scene.light_bake.npz"
    bake = _bake(rng)
    good = bake.save(path).read_bytes()
    path.write_bytes(_damage(kind, good, bake.arrays["ratio"]))
    _assert_refused(path)


def test_every_flipped_byte_is_refused_or_harmless(tmp_path, rng):
    """One byte flipped anywhere (every third byte of a whole file): load either reads the
    very same bake (a byte the zip does not check: a timestamp, a version-made-by) or raises
    LightBakeError saying to bake again, never another exception."""
    bake = _bake(rng)
    path = tmp_path / "b.light_bake.npz"
    good = bake.save(path).read_bytes()
    other: dict[str, int] = {}
    for i in range(0, len(good), 3):
        damaged = bytearray(good)
        damaged[i] ^= 0x5A
        path.write_bytes(bytes(damaged))
        try:
            back = load(path)
        except LightBakeError as exc:
            assert "bake again" in str(exc)
            continue
        except Exception as exc:
            name = type(exc).__name__
            other[name] = other.get(name, 0) + 1
            continue
        for name, array in bake.arrays.items():
            assert back.arrays[name].tobytes() == array.tobytes(), (i, name)
        assert back.meshes == bake.meshes and back.knobs == bake.knobs, i
    assert other == {}, f"exceptions other than LightBakeError: {other}"


def test_another_version_is_refused(tmp_path, rng):
    bake = _bake(rng)
    path = tmp_path / "v2.light_bake.npz"
    meta = {**bake.report(), "scene_digest": bake.scene_digest, "version": FORMAT_VERSION + 1}
    _write_npz(path, meta, bake.arrays)
    error = _assert_refused(path)
    assert f"version {FORMAT_VERSION + 1}" in str(error)


def test_the_last_version_is_refused_by_its_version(tmp_path, rng):
    """A version-3 file has no light directions: what is refused is its version (with what
    to do), not a missing array."""
    bake = _bake(rng)
    path = tmp_path / "v3.light_bake.npz"
    meta = {**bake.report(), "scene_digest": bake.scene_digest, "version": 3}
    _write_npz(path, meta, {k: v for k, v in bake.arrays.items() if k != "light_dir"})
    error = _assert_refused(path)
    assert "version 3" in str(error) and "bake again" in str(error)


@pytest.mark.parametrize("missing", ["ratio", "light_dir", "positions", "meta"])
def test_a_file_missing_an_array_is_refused(tmp_path, rng, missing):
    bake = _bake(rng)
    meta = {**bake.report(), "scene_digest": bake.scene_digest}
    arrays = {k: v for k, v in bake.arrays.items() if k != missing}
    path = tmp_path / "m.light_bake.npz"
    if missing == "meta":
        with open(path, "wb") as f:
            np.savez(f, **arrays)
    else:
        _write_npz(path, meta, arrays)
    _assert_refused(path)


def test_a_foreign_meta_is_refused(tmp_path, rng):
    """Meta of this version but without the knobs (a foreign or hand-made file)."""
    bake = _bake(rng)
    meta = {**bake.report(), "scene_digest": bake.scene_digest}
    del meta["knobs"]
    path = tmp_path / "f.light_bake.npz"
    _write_npz(path, meta, bake.arrays)
    _assert_refused(path)


@pytest.mark.parametrize(
    "ratio_shape", [(7, 4, 3), (5, 4, 3), (6, 9, 3), (6, 4, 4), (6, 12)], ids=str
)
def test_ratio_not_matching_the_points_is_refused(tmp_path, rng, ratio_shape):
    bake = _bake(rng)  # 6 points, view_bins 2: (6, 4, 3)
    bake.arrays["ratio"] = rng.random(ratio_shape).astype(np.float32)
    path = bake.save(tmp_path / "s.light_bake.npz")
    error = _assert_refused(path)
    assert "do not match its points" in str(error)


@pytest.mark.parametrize("shape", [(7, 3), (5, 3), (6, 4), (6,)], ids=str)
def test_light_directions_not_matching_the_points_are_refused(tmp_path, rng, shape):
    bake = _bake(rng)  # 6 points
    bake.arrays["light_dir"] = rng.random(shape).astype(np.float32)
    error = _assert_refused(bake.save(tmp_path / "d.light_bake.npz"))
    assert "do not match its points" in str(error)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("array", ["ratio", "light_dir"])
def test_non_finite_values_are_refused(tmp_path, rng, bad, array):
    bake = _bake(rng)
    bake.arrays[array].reshape(6, -1)[3, 2] = bad
    path = bake.save(tmp_path / "n.light_bake.npz")
    _assert_refused(path)


# --- staleness ---------------------------------------------------------------------------------


def test_an_unchanged_scene_has_no_stale_bake(rng):
    bake = _bake(rng)
    assert bake.stale(_digests(bake), "scene-1") == []


def test_a_changed_mesh_makes_itself_and_the_meshes_beside_it_stale(rng):
    bake = _bake(rng)
    digests = _digests(bake)
    digests["Ball"] = "d-ball-moved"
    # Ground was baked beside Ball (lists it); Lamp post was not; Moon was never baked.
    assert sorted(bake.stale(digests, "scene-1")) == ["Ball", "Ground"]
    digests = _digests(bake)
    digests["Lamp post"] = "d-post-moved"
    assert bake.stale(digests, "scene-1") == ["Lamp post"]


def test_a_changed_unbaked_mesh_is_never_listed(rng):
    bake = _bake(rng)
    digests = _digests(bake)
    digests["Moon"] = "d-moon-moved"
    assert bake.stale(digests, "scene-1") == []
    # ... but a baked mesh that lists it as a neighbour is stale.
    meshes = _meshes()
    meshes[2].neighbours = ["Moon"]
    assert _bake(rng, meshes=meshes).stale(digests, "scene-1") == ["Lamp post"]


def test_changed_lights_or_world_make_every_baked_mesh_stale(rng):
    bake = _bake(rng)
    stale = bake.stale(_digests(bake), "scene-2")
    assert sorted(stale) == ["Ball", "Ground", "Lamp post"]  # never the unbaked Moon


def test_a_mesh_gone_from_the_scene_is_stale(rng):
    bake = _bake(rng)
    digests = _digests(bake)
    del digests["Lamp post"]
    assert bake.stale(digests, "scene-1") == ["Lamp post"]
    del digests["Ball"]
    assert sorted(bake.stale(digests, "scene-1")) == ["Ball", "Ground", "Lamp post"]
    del digests["Moon"]  # unbaked: gone or not, never listed
    assert "Moon" not in bake.stale(digests, "scene-1")
    assert bake.stale({}, "scene-1") == ["Ground", "Ball", "Lamp post"]


def test_a_mesh_added_to_the_scene_makes_every_bake_stale(rng):
    """Conservative: a new mesh may shadow or reflect onto any baked one."""
    bake = _bake(rng)
    digests = {**_digests(bake), "New chair": "0" * 24}
    assert bake.stale(digests, "scene-1") == [m.name for m in bake.meshes if m.baked]
    assert bake.stale(_digests(bake), "scene-1") == []


#: The current analysis' neighbours (scene/bake_analysis.py current_neighbours) of the scene
#: as baked: nothing moved.
NEIGHBOURS = {"Ground": ["Ball"], "Ball": ["Ground"], "Lamp post": [], "Moon": []}


def test_with_the_current_neighbours_a_change_far_away_stales_nothing_else(rng):
    """The Moon (never baked, beside nothing) moved, far from everything: no bake is stale
    (before and after it stands beside none of them); the Lamp post moved alone: only it."""
    bake = _bake(rng)
    digests = {**_digests(bake), "Moon": "d-moon-moved"}
    assert bake.stale(digests, "scene-1", neighbours=NEIGHBOURS) == []
    digests = {**_digests(bake), "Lamp post": "d-post-moved"}
    assert bake.stale(digests, "scene-1", neighbours=NEIGHBOURS) == ["Lamp post"]


def test_a_mesh_moved_next_to_a_baked_one_stales_it(rng):
    """The Moon moved beside the Lamp post: the analysis now lists it there (new neighbours),
    though the bake did not (old neighbours)."""
    bake = _bake(rng)
    digests = {**_digests(bake), "Moon": "d-moon-moved"}
    now = {**NEIGHBOURS, "Lamp post": ["Moon"], "Moon": ["Lamp post"]}
    assert bake.stale(digests, "scene-1", neighbours=now) == ["Lamp post"]
    assert bake.why_stale(digests, "scene-1", neighbours=now) == {
        "Lamp post": "'Moon' beside it changed"
    }


def test_a_mesh_moved_away_still_stales_the_one_it_was_baked_beside(rng):
    """The Ball moved away from the Ground: the analysis no longer lists it beside the Ground,
    but the Ground's bake holds its shadow (old neighbours)."""
    bake = _bake(rng)
    digests = {**_digests(bake), "Ball": "d-ball-moved-away"}
    now = {**NEIGHBOURS, "Ground": [], "Ball": []}
    assert bake.stale(digests, "scene-1", neighbours=now) == ["Ground", "Ball"]
    assert bake.why_stale(digests, "scene-1", neighbours=now) == {
        "Ground": "'Ball' beside it changed",
        "Ball": "it changed",
    }


def test_an_added_mesh_stales_only_the_bakes_it_stands_beside(rng):
    bake = _bake(rng)
    digests = {**_digests(bake), "New chair": "0" * 24}
    far = {**NEIGHBOURS, "New chair": []}
    assert bake.stale(digests, "scene-1", neighbours=far) == []
    beside = {**NEIGHBOURS, "Ball": ["Ground", "New chair"], "New chair": ["Ball"]}
    assert bake.stale(digests, "scene-1", neighbours=beside) == ["Ball"]
    assert bake.why_stale(digests, "scene-1", neighbours=beside) == {
        "Ball": "'New chair' added beside it"
    }
    # Without the analysis (None), where it stands is not known: every bake is stale.
    assert bake.stale(digests, "scene-1") == ["Ground", "Ball", "Lamp post"]
    assert set(bake.why_stale(digests, "scene-1").values()) == {"'New chair' added to the scene"}
    # ... and so for a mesh the analysis given has no entry for (it was not analysed).
    partial = {k: v for k, v in far.items() if k != "Lamp post"}
    assert bake.stale(digests, "scene-1", neighbours=partial) == ["Lamp post"]


def test_a_removed_neighbour_stales_the_bakes_beside_it(rng):
    bake = _bake(rng)
    digests = _digests(bake)
    del digests["Ball"]
    now = {"Ground": [], "Lamp post": [], "Moon": []}
    assert bake.why_stale(digests, "scene-1", neighbours=now) == {
        "Ground": "'Ball' beside it is gone",
        "Ball": "it is gone",
    }


def test_changed_lights_or_world_stale_every_bake_whatever_the_neighbours(rng):
    bake = _bake(rng)
    stale = bake.why_stale(_digests(bake), "scene-2", neighbours=NEIGHBOURS)
    assert stale == dict.fromkeys(
        ["Ground", "Ball", "Lamp post"], "the lights or the World changed"
    )


def test_a_baked_mesh_that_needs_nothing_now_is_not_stale_and_missing_names_the_unbaked(rng):
    """The Lamp post (unchanged, nothing beside it) would not be baked now, say: its bake still
    holds, so it is not stale. The Moon needs a bake now (something moved beside it, say) and
    has none: ``missing`` names it, as it names a mesh new to the scene."""
    bake = _bake(rng)
    assert bake.stale(_digests(bake), "scene-1", neighbours=NEIGHBOURS) == []
    needed = ["Ground", "Ball", "Moon", "New chair"]  # not the Lamp post
    assert bake.missing(needed) == ["Moon", "New chair"]
    assert bake.missing(["Ground", "Lamp post"]) == []
    assert bake.missing([]) == []


def test_staleness_survives_the_round_trip(tmp_path, rng):
    bake = _bake(rng)
    back = load(bake.save(tmp_path / "r.light_bake.npz"))
    digests = _digests(bake)
    assert back.stale(digests, "scene-1") == []
    digests["Ground"] = "x"
    assert sorted(back.stale(digests, "scene-1")) == ["Ball", "Ground"]


# --- the report --------------------------------------------------------------------------------


def test_mesh_lines_say_what_was_baked_and_why():
    ground, _, post, moon = _meshes()
    assert ground.line() == (
        "Ground: shadows + interreflection baked at 3 points in 0.5 s "
        "('Ball' and it face each other: shadows and interreflection)"
    )
    assert post.line() == (
        "Lamp post: interreflection baked at 0 points in 0.0 s "
        "(non-convex: folds shadow and reflect onto itself)"
    )
    shadows_only = MeshBake(
        "Wall", "d", True, True, False, "'Roof' in front of it", points=12, seconds=2.04
    )
    assert shadows_only.line() == (
        "Wall: shadows baked at 12 points in 2.0 s ('Roof' in front of it)"
    )
    assert moon.line() == "Moon: not baked (alone and convex: nothing to bake)"


def test_lines_of_kept_and_rebaked_meshes_say_so():
    ground = _meshes()[0]
    ground.kept, ground.seconds = True, 0.0
    assert ground.line() == (
        "Ground: shadows + interreflection baked at 3 points (kept: unchanged since the last "
        "bake; 'Ball' and it face each other: shadows and interreflection)"
    )
    ball = _meshes()[1]
    ball.rebaked = "'Ground' beside it changed"
    assert ball.line() == (
        "Ball: shadows + interreflection baked at 3 points in 1.2 s ('Ground' and it face each "
        "other: shadows and interreflection); re-baked: 'Ground' beside it changed"
    )


def test_kept_travels_with_the_report_and_a_file_without_it_loads(tmp_path, rng):
    """``kept``/``rebaked`` are in the report and the file; a version-2 file written before
    they existed (no such keys) loads with them False/empty."""
    meshes = _meshes()
    meshes[0].kept = True
    meshes[1].rebaked = "it changed"
    bake = _bake(rng, meshes=meshes)
    report = bake.report()
    assert [m["kept"] for m in report["meshes"]] == [True, False, False, False]
    assert report["meshes"][1]["rebaked"] == "it changed"
    assert load(bake.save(tmp_path / "k.light_bake.npz")).meshes == meshes
    meta = {**bake.report(), "scene_digest": bake.scene_digest}
    for mesh in meta["meshes"]:
        del mesh["kept"], mesh["rebaked"]
    path = tmp_path / "before.light_bake.npz"
    _write_npz(path, meta, bake.arrays)
    back = load(path)
    assert back.meshes == _meshes()
    assert not any(m.kept or m.rebaked for m in back.meshes)


def test_report_is_json(rng):
    bake = _bake(rng)
    report = bake.report()
    text = json.dumps(report)
    back = json.loads(text)
    assert back["version"] == FORMAT_VERSION
    assert back["knobs"] == KNOBS
    assert back["seconds"] == 1.75
    assert back["bytes"] == sum(a.nbytes for a in bake.arrays.values())
    assert [MeshBake(**m) for m in back["meshes"]] == bake.meshes


def test_digest_tells_arrays_and_values_apart():
    a = np.arange(6, dtype=np.float32)
    d = light_bake.digest(a, "Grey", 3)
    assert d == light_bake.digest(a.copy(), "Grey", 3) and len(d) == 24
    assert d != light_bake.digest(a.reshape(2, 3), "Grey", 3)  # shape counts
    assert d != light_bake.digest(a.astype(np.float64), "Grey", 3)  # dtype counts
    assert d != light_bake.digest(a, "Grey", 4)
    b = a.copy()
    b[5] = np.nextafter(b[5], np.float32(10))
    assert d != light_bake.digest(b, "Grey", 3)  # one ulp counts

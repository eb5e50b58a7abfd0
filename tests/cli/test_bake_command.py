"""``bake``: a .blend's light baked for the VR preview, through the CLI (real Blender, real
OpenCL): a sphere resting on a ground, each of which shadows and reflects onto the other, so
both are baked; where the files go; the errors before any baking; the bake is the same bit for
bit when run again; run again beside its bake it keeps what is unchanged, --all bakes
everything, a damaged bake is not used."""

from __future__ import annotations

import importlib.util
import json
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import make_blend, run_cli

from btf_addon.render.light_bake import FORMAT_VERSION, GRID_ARRAYS, load

pytestmark = [
    pytest.mark.blender,
    pytest.mark.opencl,
    pytest.mark.skipif(
        importlib.util.find_spec("bpy") is None,
        reason="Blender as a Python module (pip install bpy==5.0.1)",
    ),
]

#: A UV sphere (radius 0.5, 16 × 8, flat-shaded) resting on a 2 m ground at the origin, one
#: plain Principled material (an analytic BTF), a constant grey World, this add-on's engine.
SCENE = """
bpy.ops.mesh.primitive_plane_add(size=2.0)
bpy.context.object.name = "Ground"
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0, 0, 0.5), segments=16, ring_count=8)
bpy.context.object.name = "Ball"
material = with_nodes(bpy.data.materials.new("Grey"))
for name in ("Ground", "Ball"):
    bpy.data.objects[name].data.materials.append(material)
cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
scene.collection.objects.link(cam)
cam.location = (0.0, -4.0, 2.0)
cam.rotation_euler = (1.1, 0.0, 0.0)
scene.camera = cam
world = with_nodes(bpy.data.worlds.new("W"))
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
scene.world = world
scene.render.engine = "BTF_RENDER"
"""
KNOBS = ("--spacing", "0.5", "--view-bins", "2", "--samples", "16")
NPZ = "s.Scene.light_bake.npz"
REPORT = "s.Scene.light_bake.json"  # the command's help: <file>.<scene>.light_bake.json
OBJECTS = ("Ground", "Ball")


def _listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def _report_in(folder: Path) -> dict:
    """The one JSON report in ``folder``, whatever its name (its name has its own test)."""
    (path,) = folder.glob("*.json")
    return json.loads(path.read_text())


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("bake")
    blend = folder / "s.blend"
    make_blend(blend, SCENE)
    return blend


@pytest.fixture(scope="module")
def baked(scene, tmp_path_factory) -> SimpleNamespace:
    """Two runs of the same command: into ``-o DIR`` first (nothing may appear beside the
    .blend), then beside the .blend."""
    folder = scene.parent
    out = tmp_path_factory.mktemp("out") / "bakes"  # not there yet: the command creates it
    before = _listing(folder)
    to_dir = run_cli("bake", "--blend", scene, *KNOBS, "-o", out)
    beside_after_dir = _listing(folder)
    beside = run_cli("bake", "--blend", scene, *KNOBS)
    return SimpleNamespace(
        blend=scene,
        folder=folder,
        out=out,
        before=before,
        beside_after_dir=beside_after_dir,
        to_dir=to_dir,
        beside=beside,
    )


def test_bake_writes_its_files_beside_the_blend(baked):
    assert baked.beside.returncode == 0
    new = set(_listing(baked.folder)) - set(baked.before)
    assert (baked.folder / NPZ).is_file()
    assert not [n for n in new if n.startswith(".") or ".tmp" in n], new  # no temporaries
    assert NPZ in new and len(new) == 2, new  # the bake and its report, nothing else
    assert str(baked.folder / NPZ) in baked.beside.stderr
    assert (baked.folder / REPORT).is_file(), f"report written as {sorted(new - {NPZ})}"


def test_bake_says_per_object_what_was_baked(baked):
    report = _report_in(baked.folder)
    meshes = {m["name"]: m for m in report["meshes"]}
    assert sorted(meshes) == sorted(OBJECTS)
    lines = baked.beside.stdout.splitlines()
    for name in OBJECTS:
        mesh = meshes[name]
        # Each shadows and reflects onto the other: both baked, each beside the other.
        assert mesh["baked"] and mesh["shadows"] and mesh["interreflection"], mesh
        (other,) = set(OBJECTS) - {name}
        assert mesh["neighbours"] == [other] and other in mesh["reason"], mesh
        assert mesh["points"] > 0
        mine = [line for line in lines if line.startswith(f"{name}: ")]
        assert len(mine) == 1, lines
        assert mine[0].startswith(
            f"{name}: shadows + interreflection baked at {mesh['points']} points in "
        ), mine[0]
        assert mine[0].endswith(f"({mesh['reason']})"), mine[0]
    assert report["knobs"]["spacing"] == 0.5 and report["knobs"]["view_bins"] == 2
    assert report["knobs"]["samples"] == 16  # one whole pass of 16
    assert report["version"] == FORMAT_VERSION


def test_baked_values_are_finite_and_show_the_contact(baked):
    bake = load(baked.folder / NPZ)
    report = _report_in(baked.folder)
    arrays = bake.arrays
    ratio, owner, positions = arrays["ratio"], arrays["point_mesh"], arrays["positions"]
    assert ratio.shape == (len(positions), 4, 3) and ratio.dtype == np.float32
    assert np.all(np.isfinite(ratio)) and np.all(ratio >= 0)
    assert [m.name for m in bake.meshes] == [m["name"] for m in report["meshes"]]
    assert bake.scene_digest and all(m.digest for m in bake.meshes)
    counts = np.bincount(owner, minlength=len(bake.meshes))
    for i, mesh in enumerate(bake.meshes):
        assert mesh.points == counts[i] == report["meshes"][i]["points"], mesh.name
        mine = ratio[owner == i]
        assert mine.mean() > 0.05, mesh.name
        assert np.mean(mine.max(axis=(1, 2)) > 0) > 0.95, mesh.name  # lit almost everywhere
    # The contact shadow: on the ground, the point under the sphere gets less of the World
    # than the far corners; on the sphere, the lowest points less than the top.
    ground = owner == [m.name for m in bake.meshes].index("Ground")
    ball = ~ground
    radial = np.linalg.norm(positions[ground, :2], axis=1)
    light = ratio[ground].mean(axis=(1, 2))
    assert light[radial < 0.1].max() < 0.8 * light[radial > 1.3].mean(), (radial, light)
    height = positions[ball, 2]
    lit = ratio[ball].mean(axis=(1, 2))
    assert lit[height < 0.1].mean() < 0.6 * lit[height > 0.9].mean()


def test_output_folder_and_the_same_bake_twice(baked):
    """``-o DIR`` writes there and nothing beside the .blend; the second run (beside the
    .blend) gives the same data bit for bit: the bake is deterministic for the scene's seed."""
    assert baked.to_dir.returncode == 0
    assert baked.beside_after_dir == baked.before, "-o DIR wrote beside the .blend"
    files = _listing(baked.out)
    assert NPZ in files and len(files) == 2, files
    first, second = load(baked.out / NPZ), load(baked.folder / NPZ)
    for name in (*GRID_ARRAYS, "ratio"):
        a, b = first.arrays[name], second.arrays[name]
        assert a.dtype == b.dtype and a.shape == b.shape, name
        changed = int(np.count_nonzero(a != b))
        assert a.tobytes() == b.tobytes(), f"{name}: {changed} of {a.size} values differ"
    assert first.knobs == second.knobs and first.scene_digest == second.scene_digest
    untimed = [[{**vars(m), "seconds": 0} for m in b.meshes] for b in (first, second)]
    assert untimed[0] == untimed[1]


def test_unwritable_output_fails_before_baking(scene, tmp_path):
    """An output Blender could never write: exit 2, a message naming it, no baking started,
    nothing written."""
    blocker = tmp_path / "a file"
    blocker.write_text("not a folder")
    before = _listing(scene.parent)
    cases = [(blocker, "is a file, not a folder")]
    readonly = tmp_path / "read-only"
    readonly.mkdir()
    readonly.chmod(0o500)
    try:
        probe = readonly / "probe"
        try:
            probe.touch()  # root writes anywhere: the case then proves nothing
            probe.unlink()
        except PermissionError:
            cases.append((readonly, "cannot write in"))
        for out, message in cases:
            proc = run_cli("bake", "--blend", scene, *KNOBS, "-o", out, check=False)
            assert proc.returncode == 2, proc.stderr
            assert message in proc.stderr and str(out) in proc.stderr, proc.stderr
            assert "Traceback" not in proc.stderr and "% baking" not in proc.stderr, proc.stderr
            assert " baked at " not in proc.stdout
        assert _listing(readonly) == []
    finally:
        readonly.chmod(0o700)
    assert blocker.read_text() == "not a folder"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a file", "read-only"]
    assert _listing(scene.parent) == before


def test_missing_blend_and_bad_knobs_are_refused(tmp_path):
    proc = run_cli("bake", "--blend", tmp_path / "none.blend", *KNOBS, check=False)
    assert proc.returncode == 2 and "no such .blend" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    not_blend = tmp_path / "text.blend"
    not_blend.write_text("hello")
    proc = run_cli("bake", "--blend", not_blend, check=False)
    assert proc.returncode == 2 and "not a .blend file" in proc.stderr, proc.stderr
    for flag, value in (("--spacing", "0"), ("--view-bins", "-1"), ("--samples", "0")):
        proc = run_cli("bake", "--blend", not_blend, flag, value, check=False)
        assert proc.returncode == 2 and flag in proc.stderr, proc.stderr
    assert _listing(tmp_path) == ["text.blend"]


def _same_values(a, b) -> None:
    for name in (*GRID_ARRAYS, "ratio"):
        assert a.arrays[name].tobytes() == b.arrays[name].tobytes(), name


def test_a_second_bake_keeps_what_is_unchanged_and_all_bakes_everything(baked, tmp_path):
    """The .blend and its bake copied elsewhere: run again, the bake keeps both objects (no
    tracing: no progress shown) and says so; --all traces both again (the same values: the
    bake is deterministic); a damaged bake file is not used, said in one line, and everything
    is baked."""
    blend, npz = tmp_path / "s.blend", tmp_path / NPZ
    shutil.copy(baked.blend, blend)
    shutil.copy(baked.folder / NPZ, npz)
    first = load(npz)

    kept = run_cli("bake", "--blend", blend, *KNOBS)
    again = load(npz)
    assert [m.kept for m in again.meshes] == [True, True], again.meshes
    _same_values(again, first)
    assert "% baking" not in kept.stderr, kept.stderr
    for mesh in again.meshes:
        assert (
            f"{mesh.name}: shadows + interreflection baked at {mesh.points} points (kept: "
            "unchanged since the last bake; " in kept.stdout
        ), kept.stdout
    assert "kept unchanged since the last bake: 'Ground', 'Ball'; 0 objects baked again" in (
        kept.stdout
    )
    assert [m["kept"] for m in _report_in(tmp_path)["meshes"]] == [True, True]

    everything = run_cli("bake", "--blend", blend, *KNOBS, "--all")
    whole = load(npz)
    assert not any(m.kept or m.rebaked for m in whole.meshes), whole.meshes
    assert "% baking" in everything.stderr and "kept" not in everything.stdout
    _same_values(whole, first)

    npz.write_bytes(b"not a light bake\n")
    damaged = run_cli("bake", "--blend", blend, *KNOBS)
    said = [line for line in damaged.stderr.splitlines() if "the last bake is not used" in line]
    assert len(said) == 1 and said[0].startswith("baking everything: "), damaged.stderr
    assert str(npz) in said[0] and "bake again" in said[0]
    rebaked = load(npz)
    assert not any(m.kept for m in rebaked.meshes)
    _same_values(rebaked, first)

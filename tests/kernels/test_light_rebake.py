"""Re-baking (btf_addon/cl/bake.py ``bake_scene``'s ``previous``): a mesh whose bake still holds
keeps its values, copied bit for bit, and no device work is done for it; the rest is traced,
bit for bit what a full bake of the same scene gives it (each point is seeded by its index in
the whole grid, kernels/render_direct.cl ``bake_light``); other knobs bake everything again.

The scene: a ground (2 m, facing up) and a wall standing on its edge (facing +x), which see
each other, and a cube far below and behind both. The cube sees the ground and the wall (they
lie in front of its faces: it needs a bake, shadows only) but lies behind every face of both,
so neither lists it as a neighbour: moving it stales its own bake only."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene.bake_analysis import current_neighbours
from btf_addon.scene.bake_points import build_grid
from btf_addon.scene.primitives import cube, plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

pytestmark = pytest.mark.opencl

KNOBS = dict(spacing=0.5, view_bins=2, samples=16, footprint=4, bounces=1)
FAR = (-6.0, 0.0, -6.0)  # the cube's place: behind the ground (z < 0) and the wall (x < −1)


def _placed(mesh, matrix):
    mesh.world_from_object = np.asarray(matrix, float)
    return mesh


def _translation(offset) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = offset
    return m


def _wall():
    """A 2 m square at x = −1 facing +x, z from 0 to 2 (the plane turned 90° about y)."""
    turn = np.array([[0.0, 0, 1, -1], [0, 1, 0, 0], [-1, 0, 0, 1], [0, 0, 0, 1]])
    return _placed(plane(2.0, name="Wall"), turn)


def _scene(cube_at=FAR, order=("Ground", "Wall", "Cube")) -> Scene:
    meshes = {
        "Ground": plane(2.0, name="Ground"),
        "Wall": _wall(),
        "Cube": _placed(cube(1.0, name="Cube"), _translation(cube_at)),
    }
    return Scene(
        [meshes[name] for name in order],
        [Material(LambertianBTF(0.5))],
        Camera(look_at((4.0, -6.0, 3.0), (0, 0, 0))),
        Environment.constant(np.array([0.8, 1.0, 1.2])),
    )


def _bake(scene, cl_context, previous=None, **knobs):
    from btf_addon.cl.bake import BakeKnobs, bake_scene

    return bake_scene(scene, cl_context, BakeKnobs(**{**KNOBS, **knobs}), previous=previous)


@pytest.fixture
def launched(monkeypatch) -> list[np.ndarray]:
    """The grid's points each ``bake_light`` call traces (``point_ids``), the call itself
    unchanged: what device work a bake did."""
    from btf_addon.cl import bake

    calls, real = [], bake.bake_light

    def spy(*args, point_ids=None, **kwargs):
        calls.append(np.array(point_ids))
        return real(*args, point_ids=point_ids, **kwargs)

    monkeypatch.setattr(bake, "bake_light", spy)
    return calls


@pytest.fixture(scope="module")
def first(cl_context):
    """A full bake of the scene with the cube in its far place."""
    return _bake(_scene(), cl_context)


def _rows(bake, name: str) -> np.ndarray:
    """The ratio rows of mesh ``name``'s points."""
    index = [m.name for m in bake.meshes].index(name)
    return bake.arrays["ratio"][bake.arrays["point_mesh"] == index]


def _mesh(bake, name: str):
    (mesh,) = [m for m in bake.meshes if m.name == name]
    return mesh


def test_the_scene_needs_what_the_module_says(first):
    """The premise: all three baked; the cube beside the ground and wall, they not beside it."""
    ground, wall, box = (_mesh(first, n) for n in ("Ground", "Wall", "Cube"))
    assert all(m.baked and not m.kept and m.rebaked == "" for m in (ground, wall, box))
    assert ground.neighbours == ["Wall"] and wall.neighbours == ["Ground"]
    assert sorted(box.neighbours) == ["Ground", "Wall"] and not box.interreflection
    # what LightBake.stale is given as the current neighbours: the analysis' own
    assert current_neighbours(_scene()) == {m.name: m.neighbours for m in first.meshes}
    assert first.knobs["samples"] == 16
    for name in ("Ground", "Wall", "Cube"):
        assert np.all(_rows(first, name).max(axis=(1, 2)) > 0), name  # every point traced


def test_moving_a_far_mesh_traces_only_it_and_equals_a_full_bake(first, cl_context, launched):
    moved = _scene(cube_at=(FAR[0], 0.3, FAR[2]))
    opened = []  # the context as a factory (the CLI's and the operator's way): called to trace
    again = _bake(moved, lambda: opened.append(1) or cl_context, previous=first)
    assert opened == [1]
    (ids,) = launched  # one bake_light call, for the cube's points only
    cube_index = [m.name for m in again.meshes].index("Cube")
    np.testing.assert_array_equal(ids, np.flatnonzero(again.arrays["point_mesh"] == cube_index))
    for name in ("Ground", "Wall"):
        mesh = _mesh(again, name)
        assert mesh.kept and mesh.seconds == 0.0 and mesh.rebaked == "", mesh
        assert mesh.line().endswith(f"(kept: unchanged since the last bake; {mesh.reason})")
        assert _rows(again, name).tobytes() == _rows(first, name).tobytes(), name
    box = _mesh(again, "Cube")
    assert not box.kept and box.rebaked == "it changed", box
    assert box.line().endswith("; re-baked: it changed")
    assert _rows(again, "Cube").tobytes() != _rows(first, "Cube").tobytes()  # traced anew
    # The cube traced alone gives what a full bake of the moved scene gives it, bit for bit
    # (and the kept meshes are, here, what it gives them too: same points, same seeds).
    launched.clear()
    full = _bake(moved, cl_context)
    assert len(launched) == 1 and len(launched[0]) == len(again.arrays["ratio"])
    assert _rows(again, "Cube").tobytes() == _rows(full, "Cube").tobytes()
    assert again.arrays["ratio"].tobytes() == full.arrays["ratio"].tobytes()
    assert again.knobs == full.knobs and again.scene_digest == full.scene_digest


def test_a_kept_mesh_is_found_by_name_when_the_meshes_change_order(first, cl_context, launched):
    """The moved cube first now: the ground's and wall's points lie elsewhere in the grid,
    their kept values move with them, and the cube is traced as a full bake traces it."""
    moved = _scene(cube_at=(FAR[0], 0.3, FAR[2]), order=("Cube", "Ground", "Wall"))
    again = _bake(moved, cl_context, previous=first)
    (ids,) = launched
    assert ids[0] == 0 and len(ids) == len(_rows(first, "Cube"))  # the cube's block, first
    for name in ("Ground", "Wall"):
        assert _mesh(again, name).kept
        assert _rows(again, name).tobytes() == _rows(first, name).tobytes(), name
    full = _bake(moved, cl_context)
    assert _rows(again, "Cube").tobytes() == _rows(full, "Cube").tobytes()


def test_an_unchanged_scene_is_kept_whole_without_any_device_work(first, monkeypatch):
    from btf_addon.cl import bake

    def refuse(*_args, **_kwargs):
        raise AssertionError("no device work for a scene whose bake still holds")

    monkeypatch.setattr(bake, "CLRenderer", refuse)
    monkeypatch.setattr(bake, "bake_light", refuse)
    again = _bake(_scene(), refuse, previous=first)  # no OpenCL context opened either
    assert [m.kept for m in again.meshes] == [True, True, True]
    assert again.knobs == first.knobs and again.scene_digest == first.scene_digest
    for name, array in first.arrays.items():
        assert again.arrays[name].tobytes() == array.tobytes(), name
    assert [(m.name, m.digest, m.points) for m in again.meshes] == [
        (m.name, m.digest, m.points) for m in first.meshes
    ]


@pytest.mark.parametrize(
    ("knob", "value", "says"),
    [
        ("bounces", 2, "bounces 2 → 1"),
        ("samples", 0, "samples 0 → 16"),  # a bake cancelled before its first pass ended
        ("seed", 3, "seed 3 → 0"),
    ],
    ids=["bounces", "cancelled", "seed"],
)
def test_a_last_bake_with_other_knobs_is_baked_again_whole(
    first, cl_context, launched, knob, value, says
):
    from btf_addon.render.light_bake import LightBake

    other = LightBake(first.arrays, {**first.knobs, knob: value}, first.meshes, first.scene_digest)
    again = _bake(_scene(), cl_context, previous=other)
    (ids,) = launched
    assert len(ids) == len(first.arrays["ratio"])  # every point traced
    for mesh in again.meshes:
        assert not mesh.kept and mesh.rebaked == f"the last bake's knobs differ ({says})", mesh
        assert mesh.line().endswith(f"; re-baked: the last bake's knobs differ ({says})")
    assert again.arrays["ratio"].tobytes() == first.arrays["ratio"].tobytes()  # deterministic


def test_a_mesh_moved_next_to_a_baked_one_stales_that_one(first, cl_context, launched):
    """The cube moved onto the ground, in front of the wall: both are traced again, each
    saying the cube was moved beside it (the current analysis' neighbours)."""
    again = _bake(_scene(cube_at=(0.0, 0.0, 0.5)), cl_context, previous=first)
    assert len(launched) == 1 and len(launched[0]) == len(first.arrays["ratio"])
    assert _mesh(again, "Ground").rebaked == "'Cube' beside it changed"
    assert _mesh(again, "Wall").rebaked == "'Cube' beside it changed"
    assert _mesh(again, "Cube").rebaked == "it changed"


def test_a_mesh_added_beside_one_stales_that_one_only(first, cl_context, launched):
    """A sphere added far from the ground and wall (behind both) but beside the cube (in front
    of its +y face): it is new and baked, the cube, which now lists it, is traced again, the
    ground and wall are kept."""
    scene = _scene()
    scene.meshes.append(_placed(uv_sphere(0.5, 8, 4, name="Ball"), _translation((-6, 5, -6))))
    again = _bake(scene, cl_context, previous=first)
    ball, box = _mesh(again, "Ball"), _mesh(again, "Cube")
    assert ball.baked and not ball.kept and ball.rebaked == "new since the last bake"
    assert "Ball" in box.neighbours and box.rebaked == "'Ball' added beside it", box
    assert [m.kept for m in again.meshes] == [True, True, False, False]
    (ids,) = launched
    np.testing.assert_array_equal(ids, np.flatnonzero(again.arrays["point_mesh"] >= 2))
    assert first.missing([m.name for m in again.meshes if m.baked]) == ["Ball"]


def test_a_grids_points_are_one_block_per_mesh():
    """What keeping a mesh's values relies on (cl/bake.py ``mesh_blocks``): even where two
    meshes' vertices coincide (two cubes in one place: welding stays inside a mesh)."""
    from btf_addon.cl.bake import mesh_blocks

    meshes = [cube(1.0), plane(2.0), cube(1.0), uv_sphere(0.5, 8, 4)]
    grid = build_grid([m.world_space_corners() for m in meshes], 0.3, footprint=2)
    blocks = mesh_blocks(grid.point_mesh, len(meshes))
    assert blocks is not None and blocks[-1] == grid.point_count
    assert blocks[1] - blocks[0] == blocks[3] - blocks[2] > 0  # the same cube, the same points
    for m in range(len(meshes)):
        assert np.all(grid.point_mesh[blocks[m] : blocks[m + 1]] == m)
    shuffled = grid.point_mesh[::-1]
    assert mesh_blocks(shuffled, len(meshes)) is None
    assert mesh_blocks(grid.point_mesh, 2) is None  # mesh indices past the meshes given
    assert mesh_blocks(np.zeros(0, np.int32), 2).tolist() == [0, 0, 0]

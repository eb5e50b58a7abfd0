"""Which effects a bake of each mesh must precompute (btf_addon/scene/bake_analysis.py)."""

from __future__ import annotations

import numpy as np

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene import bake_analysis
from btf_addon.scene.bake_analysis import BakeNeeds, bake_needs
from btf_addon.scene.lights import SunLight
from btf_addon.scene.primitives import cube, plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Mesh, Scene, look_at

FLIP = np.diag([1.0, -1.0, -1.0])  # half a turn about X: a plane facing −Z


def _scene(*meshes: Mesh) -> Scene:
    sun = SunLight(np.array([0.0, 0.0, 1.0]), np.ones(3))  # lights change no verdict
    return Scene(
        list(meshes),
        [Material(LambertianBTF(0.5))],
        Camera(look_at((0.0, -6.0, 2.0), (0, 0, 0))),
        Environment.constant((0.2, 0.2, 0.2)),
        lights=[sun],
    )


def _placed(mesh: Mesh, at=(0.0, 0.0, 0.0), rotation=None) -> Mesh:
    m = np.eye(4)
    m[:3, :3] = np.eye(3) if rotation is None else rotation
    m[:3, 3] = at
    mesh.world_from_object = m
    return mesh


def _flags(needs: BakeNeeds) -> tuple[bool, bool]:
    return needs.shadows, needs.interreflection


def test_lone_convex_sphere_needs_nothing():
    (needs,) = bake_needs(_scene(uv_sphere(1.0, name="Ball")))
    assert _flags(needs) == (False, False) and not needs.anything
    assert needs.name == "Ball" and needs.mesh == 0 and needs.neighbours == ()
    assert "alone and convex" in needs.reason


def test_lone_non_convex_mesh_shadows_and_reflects_onto_itself():
    # An L: a floor facing +Z and a wall at x = −1 facing +X, one mesh (a fold of 90°).
    floor, wall = plane(2.0), plane(2.0)
    turn = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # +Z → +X
    offset = np.array([-1.0, 0.0, 1.0])
    l_shape = Mesh(
        np.concatenate([floor.positions, wall.positions @ turn.T + offset]).astype(np.float32),
        np.concatenate([floor.normals, wall.normals @ turn.T]).astype(np.float32),
        np.concatenate([floor.uvs, wall.uvs]),
        np.concatenate([floor.tangents, wall.tangents]),
        name="L",
    )
    (needs,) = bake_needs(_scene(l_shape))
    assert _flags(needs) == (True, True)
    assert "non-convex" in needs.reason and needs.neighbours == ()


def test_sphere_resting_on_ground_both_shadow_and_reflect():
    ground = plane(6.0, name="Ground")
    ball = _placed(uv_sphere(0.5, name="Ball"), at=(0.0, 0.0, 0.5))  # touching at the origin
    g, b = bake_needs(_scene(ground, ball))
    assert _flags(g) == (True, True) and _flags(b) == (True, True)
    assert g.neighbours == ("Ball",) and b.neighbours == ("Ground",)
    assert "'Ball'" in g.reason and "face each other: shadows and interreflection" in g.reason
    assert "'Ground'" in b.reason and "non-convex" not in b.reason


def test_facing_planes_reflect_onto_each_other():
    low = plane(2.0, name="Low")
    high = _placed(plane(2.0, name="High"), at=(0.0, 0.0, 1.0), rotation=FLIP)
    a, b = bake_needs(_scene(low, high))
    # Each also hides part of the other's sky: shadows too.
    assert _flags(a) == (True, True) and _flags(b) == (True, True)
    assert a.neighbours == ("High",) and b.neighbours == ("Low",)
    assert "face each other" in a.reason


def test_planes_back_to_back_need_nothing():
    up = plane(2.0, name="Up")
    down = _placed(plane(2.0, name="Down"), at=(0.0, 0.0, -1.0), rotation=FLIP)
    for needs in bake_needs(_scene(up, down)):
        assert _flags(needs) == (False, False) and needs.neighbours == ()
        assert "no other mesh in front of it" in needs.reason


def test_sphere_below_a_plane_is_shadowed_but_not_lit_by_it():
    roof = plane(2.0, name="Roof")  # faces +Z, away from the sphere
    ball = _placed(uv_sphere(0.2, 16, 8, name="Ball"), at=(0.0, 0.0, -5.0))
    r, b = bake_needs(_scene(roof, ball))
    # The sphere lies behind the roof's plane: nothing of it is where the roof's light comes from.
    assert _flags(r) == (False, False) and r.neighbours == ()
    # The roof lies in front of the sphere's upper faces and hides part of their sky: occlusion
    # does not care which side of the roof faces down. But the side the sphere sees is the
    # roof's back, which reflects nothing (a BTF is measured over its front hemisphere), so
    # there is no interreflection to bake.
    assert _flags(b) == (True, False) and b.neighbours == ("Roof",)
    assert "'Roof' in front of it, facing away: shadows only" in b.reason


def test_degenerate_meshes_do_not_crash():
    empty = Mesh(*(np.zeros((0, k), np.float32) for k in (3, 3, 2, 4)), name="Empty")
    point = np.zeros((6, 3), np.float32)  # two triangles collapsed to a point
    up = np.tile(np.float32([0.0, 0.0, 1.0]), (6, 1))
    flat = Mesh(point, up, np.zeros((6, 2), np.float32), np.zeros((6, 4), np.float32), name="Dot")
    one = Mesh(
        np.float32([[0, 0, 1], [1, 0, 1], [0, 1, 1]]),
        up[:3],
        np.float32([[0, 0], [1, 0], [0, 1]]),
        np.float32([[1, 0, 0, 1]] * 3),
        name="Tri",
    )
    nan = cube(1.0, name="NaN")
    nan.positions[:3] = np.nan  # world_space_corners drops that triangle; 11 stay
    nan.world_from_object[:3, 3] = (5.0, 0.0, 0.0)
    zero = _placed(cube(1.0, name="Flat"), rotation=np.zeros((3, 3)))  # Blender's scale 0
    e, f, t, n, z = bake_needs(_scene(empty, flat, one, nan, zero))
    assert _flags(e) == (False, False) and "empty" in e.reason
    assert _flags(f) == (False, False) and "no triangle with area" in f.reason
    assert _flags(z) == (False, False)
    # The triangle (z = 1, facing up) has the cube at x = 5 (z ∈ [−0.5, 0.5], one triangle
    # dropped for its NaN, still convex) below its plane; the triangle lies in front of the
    # cube's top and −X faces, but faces away from it: the cube is shadowed only.
    assert _flags(t) == (False, False)
    assert _flags(n) == (True, False) and n.neighbours == ("Tri",)
    (alone,) = bake_needs(_scene(one))
    assert _flags(alone) == (False, False) and "alone and convex" in alone.reason
    assert bake_needs(_scene()) == []


def test_work_bound_answers_conservatively(monkeypatch):
    up = plane(2.0, name="Up")
    down = _placed(plane(2.0, name="Down"), at=(0.0, 0.0, -1.0), rotation=FLIP)
    monkeypatch.setattr(bake_analysis, "MAX_BAKE_WORK", 10)
    for needs in bake_needs(_scene(up, down)):  # truly nothing (test above), but unchecked
        assert _flags(needs) == (True, True)
        assert "skipped" in needs.reason and "MAX_BAKE_WORK" in needs.reason


def test_box_candidates_are_checked_against_the_vertices(monkeypatch):
    # Two parallel planes facing (0, 1, 1)/√2, "Back" 1.5/√2 behind "Front": Back's box reaches
    # in front of Front's plane (its corner at y = z ≈ 1.37), none of its vertices does.
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, 0.5**0.5, 0.5**0.5], [0.0, -(0.5**0.5), 0.5**0.5]])
    front = _placed(plane(2.0, name="Front"), rotation=tilt)
    back = _placed(plane(6.0, name="Back"), at=(0.0, -0.75, -0.75), rotation=tilt)
    f, b = bake_needs(_scene(front, back))
    assert _flags(f) == (False, False)
    assert _flags(b) == (True, False) and b.neighbours == ("Front",)
    # Budget for the first pair's box test (2 faces) but not its 2 × 4 vertex tests.
    monkeypatch.setattr(bake_analysis, "MAX_BAKE_WORK", bake_analysis.PAIR_COST + 2 + 7)
    f, b = bake_needs(_scene(front, back))
    assert _flags(f) == (True, True) and "'Back' skipped past MAX_BAKE_WORK" in f.reason

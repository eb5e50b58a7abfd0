"""Which eye a draw is for (render/stereo.py), from matrices built here independently: eyes at
∓IPD/2 along a head's right axis, OpenGL frusta from tangents of the four FOV angles."""

from __future__ import annotations

import numpy as np

from btf_addon.render.stereo import SAME_EYE_M, EyeIdentifier
from btf_addon.scene.scene import look_at

IPD = 0.064


def head_and_eyes(position=(0.3, -2.0, 1.6), target=(0.0, 0.0, 1.0)):
    world_from_head = look_at(position, target)
    views = {}
    for name, sign in (("left", -1.0), ("right", 1.0)):
        world_from_eye = world_from_head.copy()
        world_from_eye[:3, 3] += sign * IPD / 2 * world_from_head[:3, 0]
        views[name] = np.linalg.inv(world_from_eye)
    return world_from_head, views


def frustum(left, right, down, up, near=0.1, far=100.0):
    """glFrustum from tangents (l < 0 < r, d < 0 < u)."""
    lo, hi, d, u = (near * t for t in (left, right, down, up))
    return np.array(
        [
            [2 * near / (hi - lo), 0, (hi + lo) / (hi - lo), 0],
            [0, 2 * near / (u - d), (u + d) / (u - d), 0],
            [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
            [0, 0, -1, 0],
        ]
    )


SYMMETRIC = frustum(-1.0, 1.0, -0.8, 0.8)


def test_the_viewer_pose_tells_left_from_right_and_the_offset():
    head, views = head_and_eyes()
    ident = EyeIdentifier()
    for name in ("left", "right"):
        eye = ident.identify(views[name], SYMMETRIC, head[:3, 3])
        assert eye.key == name and eye.rule == "viewer pose"
        assert np.isclose(eye.offset, (-1 if name == "left" else 1) * IPD / 2)
    mono = ident.identify(np.linalg.inv(head), SYMMETRIC, head[:3, 3])
    assert mono.key == "mono" and mono.offset == 0.0


def test_navigation_scale_and_far_positions_keep_the_sign():
    """Eyes 64 µm apart in world units (navigation scale 1/1000) near the origin, and 64 mm
    apart 2 km from it: both above the float32 position noise the tolerance allows for."""
    for position, target, scale in (
        ((0.3, -2.0, 1.6), (0.0, 0.0, 1.0), 1e-3),
        ((1000.0, -2000.0, 50.0), (1000.0, 0.0, 50.0), 1.0),
    ):
        head, _ = head_and_eyes(position, target)
        eye = head.copy()
        eye[:3, 3] -= 0.5 * IPD * scale * head[:3, 0]
        found = EyeIdentifier().identify(np.linalg.inv(eye), SYMMETRIC, head[:3, 3])
        assert found.key == "left", position


def test_without_a_pose_the_frustum_skew_tells_the_eye():
    """Headset frusta reach further outwards than towards the nose."""
    _, views = head_and_eyes()
    ident = EyeIdentifier()
    left = ident.identify(views["left"], frustum(-1.2, 0.9, -1.0, 1.0))
    right = ident.identify(views["right"], frustum(-0.9, 1.2, -1.0, 1.0))
    assert (left.key, right.key) == ("left", "right")
    assert left.rule == right.rule == "projection skew"


def test_without_pose_or_skew_positions_keep_two_eyes_apart():
    """Symmetric frusta and no pose: the first two distinct positions are two eyes; a later
    draw (the head moved 3 mm) goes to the nearer one; a third position never makes a third."""
    _, views = head_and_eyes()
    ident = EyeIdentifier()
    first = ident.identify(views["left"], SYMMETRIC).key
    second = ident.identify(views["right"], SYMMETRIC).key
    assert first != second
    assert ident.identify(views["left"], SYMMETRIC).key == first
    _, moved = head_and_eyes(position=(0.303, -2.0, 1.6))
    assert ident.identify(moved["right"], SYMMETRIC).key == second
    assert ident.identify(moved["left"], SYMMETRIC).key == first
    far = np.linalg.inv(look_at((5.0, 5.0, 5.0), (0.0, 0.0, 0.0)))
    assert ident.identify(far, SYMMETRIC).key in (first, second)
    assert len(ident.positions) == 2 and SAME_EYE_M < IPD

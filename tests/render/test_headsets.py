"""Headset profiles and stereo maths (render/headsets.py) against independent constructions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from btf_addon.render.headsets import (
    PROFILES,
    Eye,
    EyeFov,
    HeadsetProfile,
    eye_view_matrices,
    profile,
    projection_from_fov,
    stereo_eyes,
)
from btf_addon.scene.scene import look_at

# Matrices here are products of a few float64 operations on O(1) numbers: 1e-12 is far below
# any real error (a wrong sign or factor shows as O(1)) and far above rounding (~1e-15).
EXACT = 1e-12


def glu_perspective(fov_y: float, aspect: float, near: float, far: float) -> np.ndarray:
    """The classic gluPerspective matrix, written from its manual page."""
    f = 1 / math.tan(fov_y / 2)
    return np.array(
        [
            [f / aspect, 0, 0, 0],
            [0, f, 0, 0],
            [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
            [0, 0, -1, 0],
        ]
    )


def ndc(clip_from_view: np.ndarray, point) -> np.ndarray:
    clip = clip_from_view @ np.append(np.asarray(point, dtype=np.float64), 1.0)
    return clip[:3] / clip[3]


def test_symmetric_fov_equals_glu_perspective():
    fov_y, aspect = math.radians(70), 1.25
    half_x = math.atan(aspect * math.tan(fov_y / 2))
    fov = EyeFov(-half_x, half_x, fov_y / 2, -fov_y / 2)
    m = projection_from_fov(fov, 0.1, 50.0)
    assert m.shape == (4, 4) and m.dtype == np.float64
    np.testing.assert_allclose(m, glu_perspective(fov_y, aspect, 0.1, 50.0), atol=EXACT)


def test_asymmetric_fov_edges_land_on_the_ndc_borders():
    """A point on each side of the frustum projects to that side of NDC; near and far planes
    to z = −1 and +1 (OpenGL), whatever the asymmetry."""
    fov = EyeFov(-0.9, 0.6, 0.7, -0.8)
    near, far = 0.05, 20.0
    m = projection_from_fov(fov, near, far)
    d = 3.0  # a depth between the planes
    assert ndc(m, (math.tan(-0.9) * d, 0.0, -d))[0] == pytest.approx(-1.0, abs=EXACT)
    assert ndc(m, (math.tan(0.6) * d, 0.0, -d))[0] == pytest.approx(1.0, abs=EXACT)
    assert ndc(m, (0.0, math.tan(0.7) * d, -d))[1] == pytest.approx(1.0, abs=EXACT)
    assert ndc(m, (0.0, math.tan(-0.8) * d, -d))[1] == pytest.approx(-1.0, abs=EXACT)
    assert ndc(m, (0.0, 0.0, -near))[2] == pytest.approx(-1.0, abs=EXACT)
    # far: the z row's large terms cancel, so rounding grows with far/near (here 400×)
    assert ndc(m, (0.0, 0.0, -far))[2] == pytest.approx(1.0, abs=1e-9)


def test_fov_validation_and_tangents():
    with pytest.raises(ValueError, match="angle_left < angle_right"):
        EyeFov(0.5, -0.5, 0.5, -0.5)
    with pytest.raises(ValueError, match="π/2"):
        EyeFov(-1.6, 0.5, 0.5, -0.5)
    with pytest.raises(ValueError, match="near"):
        projection_from_fov(EyeFov(-0.5, 0.5, 0.5, -0.5), 1.0, 1.0)
    fov = EyeFov.from_tangents(-1.0, 0.5, 1.0, -1.0)
    assert fov.angle_left == pytest.approx(-math.pi / 4, abs=EXACT)
    assert fov.mirrored() == EyeFov(-math.atan(0.5), math.pi / 4, math.pi / 4, -math.pi / 4)


def test_eye_views_are_ipd_apart_and_mirror_each_other():
    world_from_head = look_at((1.0, -3.0, 1.6), (0.2, 0.0, 0.9))
    ipd = 0.064
    views = eye_view_matrices(world_from_head, ipd)
    left, right = (np.linalg.inv(views[n])[:3, 3] for n in ("left", "right"))
    head = world_from_head[:3, 3]
    assert np.linalg.norm(right - left) == pytest.approx(ipd, abs=EXACT)
    np.testing.assert_allclose((left + right) / 2, head, atol=EXACT)  # centred on the head
    # the left eye lies along the head's −x, the right along +x
    x_axis = world_from_head[:3, 0]
    assert np.dot(left - head, x_axis) == pytest.approx(-ipd / 2, abs=EXACT)
    # same orientation for both: the views differ by a translation along the view's x only
    np.testing.assert_allclose(views["left"][:3, :3], views["right"][:3, :3], atol=EXACT)
    delta = views["left"][:3, 3] - views["right"][:3, 3]
    np.testing.assert_allclose(delta, (ipd, 0.0, 0.0), atol=EXACT)
    # both look down the head's −z
    forward = -world_from_head[:3, 2]
    for v in views.values():
        np.testing.assert_allclose(np.linalg.inv(v)[:3, 2], -forward, atol=EXACT)
    with pytest.raises(ValueError, match="4, 4"):
        eye_view_matrices(np.eye(3), ipd)


def test_a_point_ahead_shows_positive_disparity():
    """A point straight ahead at 2 m lands right of centre in the left eye and left of it in
    the right eye, by the pinhole formula x_ndc = (ipd/2) / d / tan(half FOV) each."""
    world_from_head = look_at((0.0, -2.0, 1.5), (0.0, 0.0, 1.5))
    p = profile("simulated")
    left, right = stereo_eyes(p, world_from_head)
    point = np.array([0.0, 0.0, 1.5, 1.0])
    x = {}
    for eye in (left, right):
        clip = eye.clip_from_world @ point
        x[eye.name] = clip[0] / clip[3]
    expected = (p.ipd_m / 2) / 2.0 / math.tan(0.74)
    assert x["left"] == pytest.approx(expected, rel=1e-9)
    assert x["right"] == pytest.approx(-expected, rel=1e-9)
    assert x["left"] > x["right"]


def test_stereo_eyes_carry_the_profile():
    head = np.eye(4)
    p = profile("generic-2016x2240")
    eyes = stereo_eyes(p, head, near=0.2, far=30.0)
    assert [e.name for e in eyes] == ["left", "right"]
    assert all(isinstance(e, Eye) and (e.width, e.height) == (2016, 2240) for e in eyes)
    np.testing.assert_allclose(
        eyes[0].clip_from_view, projection_from_fov(p.fov_left_eye, 0.2, 30.0), atol=EXACT
    )
    np.testing.assert_allclose(
        eyes[1].clip_from_world,
        eyes[1].clip_from_view @ eyes[1].view_from_world,
        atol=EXACT,
    )
    np.testing.assert_allclose(eyes[0].position, (-p.ipd_m / 2, 0.0, 0.0), atol=EXACT)


def test_profiles_hold_the_numbers_the_brief_names():
    assert {"xtal-8k", "xtal-3", "generic-2016x2240", "simulated"} <= set(PROFILES)
    xtal = profile("xtal-8k")
    assert (xtal.eye_width, xtal.eye_height) == (3840, 2160)
    generic = profile("generic-2016x2240")
    assert (generic.eye_width, generic.eye_height, generic.refresh_hz) == (2016, 2240, 90.0)
    assert generic.frame_budget_s == pytest.approx(1 / 90)
    sim = profile("simulated")
    assert (sim.eye_width, sim.eye_height) == (320, 240)
    for p in PROFILES.values():
        assert p.name in PROFILES and p.source  # every profile says where its numbers are from
        for fov in (p.fov_left_eye, p.fov_right_eye):
            assert fov.angle_left < 0 < fov.angle_right and fov.angle_down < 0 < fov.angle_up
    # the XTAL's nominal frustum gives its 16:9 panel square pixels
    f = xtal.fov_left_eye
    ratio = (math.tan(f.angle_right) - math.tan(f.angle_left)) / (
        math.tan(f.angle_up) - math.tan(f.angle_down)
    )
    assert ratio == pytest.approx(3840 / 2160, rel=1e-12)


def test_scaled_changes_only_the_resolution():
    p = profile("xtal-8k")
    small = p.scaled(1 / 24)
    assert (small.eye_width, small.eye_height) == (160, 90)
    assert (small.fov_left_eye, small.ipd_m, small.refresh_hz) == (
        p.fov_left_eye,
        p.ipd_m,
        p.refresh_hz,
    )
    tiny = p.scaled(1e-6)
    assert (tiny.eye_width, tiny.eye_height) == (1, 1)
    with pytest.raises(ValueError, match="positive"):
        p.scaled(0)
    with pytest.raises(ValueError):
        HeadsetProfile("bad", "bad", 0, 10, p.fov_left_eye, p.fov_right_eye, 0.06, 90.0, "x")


def test_unknown_profile_lists_the_known_names():
    with pytest.raises(ValueError) as err:
        profile("vive-pro-9000")
    message = str(err.value)
    assert "vive-pro-9000" in message
    for name in PROFILES:
        assert name in message

"""Tangent generation and camera projection: the plain-array scene."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, look_at
from btf_addon.scene.tangents import corner_tangents


def test_plane_tangent_follows_u():
    t = plane().tangents
    np.testing.assert_allclose(t[:, :3], np.tile([1.0, 0.0, 0.0], (6, 1)), atol=1e-6)
    assert np.all(t[:, 3] == 1.0)


def test_mirrored_uvs_flip_the_bitangent_sign():
    p = plane()
    mirrored_uv = p.uvs.copy()
    mirrored_uv[:, 0] = 1.0 - mirrored_uv[:, 0]
    t = corner_tangents(p.positions, p.normals, mirrored_uv)
    np.testing.assert_allclose(t[:, :3], np.tile([-1.0, 0.0, 0.0], (6, 1)), atol=1e-6)
    assert np.all(t[:, 3] == -1.0)


def test_degenerate_uvs_and_triangles_get_a_valid_frame():
    p = plane()
    uvs = np.zeros_like(p.uvs)  # all corners on one UV point: no derivative exists
    positions = p.positions.copy()
    positions[3:6] = positions[3]  # a zero-area triangle
    t = corner_tangents(positions, p.normals, uvs)
    assert np.all(np.isfinite(t))
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(np.sum(t[:, :3] * p.normals, axis=1), 0.0, atol=1e-6)


def test_sphere_tangents_are_orthonormal_to_normals():
    s = uv_sphere(segments=16, rings=8)
    np.testing.assert_allclose(np.linalg.norm(s.tangents[:, :3], axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(np.sum(s.tangents[:, :3] * s.normals, axis=1), 0.0, atol=1e-5)


@pytest.mark.parametrize("perspective", [True, False])
def test_projection_maps_the_view_centre_to_the_image_centre(perspective):
    cam = Camera(look_at((3.0, -4.0, 2.0), (0.0, 0.0, 0.5)), perspective=perspective)
    clip = cam.projection(16 / 9) @ np.linalg.inv(cam.world_from_camera) @ [0.0, 0.0, 0.5, 1.0]
    np.testing.assert_allclose(clip[:2] / clip[3], 0.0, atol=1e-9)
    assert -1 < clip[2] / clip[3] < 1

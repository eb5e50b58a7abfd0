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


def test_world_space_corners_of_a_scale_of_zero_are_the_limit_of_a_tiny_scale():
    """Blender lets an object be scaled to 0 (a common way to hide one): its matrix has no
    inverse for the normals. Flattened on one axis, the object keeps every triangle with the
    normals a scale of 1e-9 gives (its plane's, the poles' own); collapsed on all three it
    keeps finite rows (triangles without area); a non-finite matrix drops every triangle;
    an invertible matrix is as before: the inverse-transpose, the mirror flipping the sign."""
    sphere = uv_sphere(1.0, 8, 4)

    def corners(diagonal):
        sphere.world_from_object = np.diag([*diagonal, 1.0])
        return sphere.world_space_corners()

    flat, tiny = corners([0.0, 1.0, 1.0]), corners([1e-9, 1.0, 1.0])
    assert flat.shape == tiny.shape == (3 * sphere.triangle_count, 12)
    np.testing.assert_allclose(flat[:, 3:6], tiny[:, 3:6], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(flat[:, 3:6], axis=1), 1.0, atol=1e-6)
    point = corners([0.0, 0.0, 0.0])
    assert np.all(np.isfinite(point)) and np.all(point[:, :3] == 0.0)
    sphere.world_from_object = np.full((4, 4), np.nan)
    assert sphere.world_space_corners().shape == (0, 12)
    mirrored = corners([-2.0, 1.0, 0.5])
    expected = sphere.normals @ np.linalg.inv(np.diag([-2.0, 1.0, 0.5]))
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    np.testing.assert_allclose(mirrored[:, 3:6], expected, atol=1e-6)
    assert np.all(mirrored[:, 11] == -sphere.tangents[:, 3])

"""core/mat4.py: the closed-form 4 × 4 inverse agrees with LAPACK's, and refuses singular
matrices as LAPACK does (and NaN, which LAPACK would pass on)."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.mat4 import inverse
from btf_addon.scene.scene import Camera, look_at


def test_inverse_agrees_with_lapack_on_the_matrices_the_eyes_use(rng):
    cases = [np.eye(4), look_at((1.0, -4.0, 0.5), (0.0, 0.0, 0.0))]
    camera = Camera(look_at((0.3, -5.0, 2.0), (0.0, 0.0, 0.0)))
    cases.append(camera.clip_from_world(16 / 9))  # a projection: far from orthogonal
    cases += [rng.normal(size=(4, 4)) for _ in range(200)]
    for m in cases:
        expected = np.linalg.inv(m)
        # Both are float64 eliminations: equal to a few ulps of the condition number's scale.
        scale = np.linalg.cond(m) * np.abs(expected).max()
        np.testing.assert_allclose(inverse(m), expected, rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(inverse(m) @ m, np.eye(4), atol=1e-12 * np.linalg.cond(m))


@pytest.mark.parametrize("bad", [np.zeros((4, 4)), np.ones((4, 4)), np.full((4, 4), np.nan)])
def test_a_singular_matrix_is_refused_as_lapack_refuses_it(bad):
    with pytest.raises(np.linalg.LinAlgError):
        inverse(bad)

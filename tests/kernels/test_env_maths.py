"""The final render's angle and environment maths against float64 numpy: ``btf_atan2``
(kernels/include/btf_packed.h: the decode's polynomial atan over the whole circle, in place of
PoCL's scalar atan2), ``btf_theta_phi_deg`` (a direction's angles for the BTF's decode, through
it) and ``env_pdf`` (kernels/render_direct.cl: the solid-angle density of a direction and its
pixel) against core/sampling/envmap.py ``Environment``, rotated and not, poles included."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import render_program_with, run_kernel

from btf_addon.core.sampling.envmap import Environment

TEST_KERNELS = """
__kernel void atan2_test(__global const float *y, __global const float *x, __global float *out)
{
  int i = get_global_id(0);
  out[i] = btf_atan2(y[i], x[i]);
}

__kernel void angles_test(__global const float *dirs, __global float *out)
{
  int i = get_global_id(0);
  vstore2(btf_theta_phi_deg(vload3(i, dirs)), i, out);
}

__kernel void pdf_test(__global const float *dirs, __global const float *row_pdf,
                       __global const float *col_pdf, const int w, const int h,
                       const float rotation, __global float *pdf, __global int *pixel)
{
  int i = get_global_id(0);
  int p;
  float sin_t;
  pdf[i] = env_pdf(row_pdf, col_pdf, w, h, rotation, vload3(i, dirs), &p, &sin_t);
  pixel[i] = p;
}
"""


@pytest.fixture(scope="module")
def program(cl_context):
    return render_program_with(cl_context, TEST_KERNELS)


def test_btf_atan2_matches_libm_over_the_whole_circle(cl_context, program):
    import pyopencl as cl

    angles = np.linspace(-np.pi, np.pi, 40001)
    radius = np.repeat([1e-30, 1e-3, 1.0, 7e4], len(angles) // 4 + 1)[: len(angles)]
    y, x = (radius * np.sin(angles)), (radius * np.cos(angles))
    # axes and signed zeros: atan2(±0, −1) = ±π, atan2(±0, +0) = ±0, (0, −0) → π
    y = np.concatenate([y, [0.0, -0.0, 0.0, -0.0, 1.0, -1.0, 0.0, -0.0]]).astype(np.float32)
    x = np.concatenate([x, [-1.0, -1.0, 0.0, 0.0, 0.0, 0.0, -0.0, -0.0]]).astype(np.float32)
    out = np.empty(len(y), np.float32)
    run_kernel(cl_context, cl.Kernel(program, "atan2_test"), len(y), [y, x], [out])
    expected = np.arctan2(y.astype(np.float64), x.astype(np.float64))
    # the polynomial's 1.1e-7 rad, plus float32 rounding of a result up to π (1.2e-7) and of
    # π − a near ±π: 4e-7 rad, a 4e-8 of a turn (an environment pixel is 1/width of one).
    np.testing.assert_allclose(out, expected, rtol=0, atol=4e-7)
    assert np.array_equal(np.signbit(out[-8:]), np.signbit(expected[-8:]))


def test_direction_angles_match_libm_at_poles_and_seams(cl_context, program):
    """θ = atan2(|d.xy|, d.z) and φ in [0, 360) against float64 acos and atan2 of the unit
    vector: random directions of three lengths (the decode's callers pass unit vectors; the
    angles must not care), the poles, directions 1e-4 from them and the seam φ = 0/360.
    φ in [0, 360]: just below 0 rounds to 360.0 in float32, as it did through libm."""
    import pyopencl as cl

    rng = np.random.default_rng(3)
    unit = rng.normal(size=(30000, 3))
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    special = np.array(
        [
            [0, 0, 1],
            [0, 0, -1],
            [1e-4, 0, 1],
            [0, -1e-4, -1],
            [1, 0, 0],
            [1, -1e-7, 0],
            [1, 1e-7, 0],
            [-1, 0, 0],
            [0, 1, 0],
            [0, -1, 0],
        ],
        dtype=np.float64,
    )
    unit = np.concatenate([unit, special / np.linalg.norm(special, axis=1, keepdims=True)])
    scale = np.repeat([1.0, 0.999, 3.0], len(unit) // 3 + 1)[: len(unit), None]
    dirs = (unit * scale).astype(np.float32)
    out = np.empty((len(dirs), 2), np.float32)
    run_kernel(cl_context, cl.Kernel(program, "angles_test"), len(dirs), [dirs], [out])
    d = dirs.astype(np.float64)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    theta = np.degrees(np.arccos(np.clip(d[:, 2], -1.0, 1.0)))
    phi = np.mod(np.degrees(np.arctan2(d[:, 1], d[:, 0])), 360.0)
    # btf_atan2's 4e-7 rad (test above) in degrees, and float32 rounding of up to 360°
    # (3e-5°); φ compared on the circle (359.99999° and 0° are neighbours)
    np.testing.assert_allclose(out[:, 0], theta, rtol=0, atol=1e-4)
    gap = np.abs(np.mod(out[:, 1] - phi + 180.0, 360.0) - 180.0)
    assert gap.max() < 1e-4
    # a φ just below 0 rounds to 360.0 in float32 (as with libm's atan2): the decode wraps it
    assert ((out[:, 1] >= 0.0) & (out[:, 1] <= 360.0)).all()


@pytest.mark.parametrize("rotation", [0.0, 0.7, -2.5])
def test_env_pdf_and_pixel_match_the_environment(cl_context, program, rotation):
    import pyopencl as cl

    rng = np.random.default_rng(5)
    image = rng.gamma(0.5, 1.0, size=(64, 128, 3))
    env = Environment(image, rotation_z_rad=rotation)
    dirs = rng.normal(size=(20000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    poles = np.array([[0, 0, 1], [0, 0, -1], [1e-4, 0, 1], [0, -1e-4, -1]], dtype=np.float64)
    dirs = np.concatenate([dirs, poles / np.linalg.norm(poles, axis=1, keepdims=True)])
    n = len(dirs)
    pdf, pixel = np.empty(n, np.float32), np.empty(n, np.int32)
    tables = [a.astype(np.float32).ravel() for a in (env.row_pdf, env.col_pdf)]
    run_kernel(
        cl_context,
        cl.Kernel(program, "pdf_test"),
        n,
        [dirs.astype(np.float32).ravel(), *tables, np.int32(128), np.int32(64),
         np.float32(rotation)],
        [pdf, pixel],
    )  # fmt: skip
    row, col = env._pixel(*env.image_coords(dirs))
    same = pixel == row * 128 + col
    # float32 directions move a pixel boundary by ~1e-7 of a turn: a few of 20 000 at most
    assert np.count_nonzero(~same) <= 20, np.count_nonzero(~same)
    # Where the pixel agrees the density is the same up to float32 rounding. Within 0.001 of a
    # pole it is not: sin θ there is √((1 − z)(1 + z)) of a z rounded to float32 (6e-8), so
    # 1 − z carries 1e-4 of relative error in any float32 formula (sin(acos z) as before too).
    away = same & (np.abs(dirs[:, 2]) < 0.999)
    np.testing.assert_allclose(pdf[away], env.pdf(dirs)[away], rtol=2e-5)
    assert np.all(np.isfinite(pdf)) and np.all(pdf > 0)  # the poles included

"""Numerical hard cases for every codec: grazing, poles, NaN/Inf, zero-length, wrap-around."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from helpers import shared_material

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF, PrincipledBTF
from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.codecs.svd_build import factorise


def _codecs():
    yield "lambertian", lambda: LambertianBTF(0.8)
    yield "ggx", lambda: GGXBTF(0.8, 0.3)
    yield "ggx-rough0", lambda: GGXBTF(0.8, 0.0)
    yield "principled", lambda: PrincipledBTF((0.9, 0.6, 0.3), 0.5, 0.5, 1.0)
    yield "dense", lambda: tabulate(LambertianBTF(0.6))
    yield "woven", lambda: woven(texels=4, fine_per_texel=4)
    yield "mlvq", lambda: MLVQBTF.from_directory(shared_material("alu"))
    yield "svd", lambda: factorise(tabulate(LambertianBTF(0.6)).data * np.pi, ranks=(2, 1, 1))[0]


CODECS = dict(_codecs())


#: Largest allowed jump between 0.125° steps, as a fraction of the sweep's maximum. 6%: the
#: steep flank of a roughness-0.3 GGX lobe. Woven: near-grazing views, masking moves a view
#: ray's hit from the red warp (G albedo 0.18) to the pale weft (G 0.8) thread — a real
#: occlusion edge — and a texel averages 4 ray-cast points, so one switch moves G by up to
#: (0.8 − 0.18)/π/4 ≈ 0.05 ≈ 25% of the sweep's maximum (~0.2); measured 28% with the shading
#: terms, so the bound is 1/3. A roughness-0 GGX is a near-delta lobe (α = 1e-4): any finite
#: step jumps across it, so only finiteness is checked there.
MAX_STEP = {"woven": 1 / 3, "ggx-rough0": None}


@pytest.fixture(params=list(CODECS))
def btf(request):
    instance = CODECS[request.param]()
    instance.test_name = request.param
    return instance


def test_invalid_inputs_give_zero_without_warnings(btf):
    nan, inf = np.nan, np.inf
    uv = np.array([[0.5, 0.5]] * 6 + [[nan, 0.2], [inf, 0.1]])
    wi = np.array(
        [
            [nan, 0, 1],
            [inf, 0, 1],
            [0, 0, 0],
            [0, 0, 1],
            [0, 0, -1],
            [1e-300, 0, 0],
            [0, 0, 1],
            [0, 0, 1],
        ]
    )
    wo = np.array(
        [[0, 0, 1], [0, 0, 1], [0, 0, 1], [0, -inf, 1], [0, 0, 1], [0, 0, 1], [0, 0, 1], [0, 0, 1]]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        v = btf.evaluate(uv, wi, wo)
        q = btf.evaluate_angles(
            [
                [0.5, 0.5, nan, 0, 0, 0],
                [0.5, 0.5, 10, inf, 0, 0],
                [0.5, 0.5, 91, 0, 0, 0],
                [0.5, 0.5, 0, 0, 120, 0],
            ]
        )
    assert np.all(v[:5] == 0) and np.all(v[6:] == 0)
    assert np.all(q == 0)
    assert np.all(np.isfinite(v[5])) and v[5].min() >= 0  # tiny but valid: light at the horizon


def test_values_stay_finite_non_negative_and_continuous_to_the_horizon(btf):
    """Sweep light and view θ to 90° at several azimuths: finite, ≥ 0, no jumps."""
    thetas = np.linspace(0.0, 90.0, 721)
    for phi in (0.0, 45.0, 180.0, 300.0):
        for which in (2, 4):  # light sweep, view sweep
            q = np.tile([0.37, 0.61, 30.0, 20.0, 40.0, 200.0], (len(thetas), 1))
            q[:, which] = thetas
            q[:, which + 1] = phi
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                v = btf.evaluate_angles(q)
            assert np.all(np.isfinite(v)) and v.min() >= 0
            bound = MAX_STEP.get(btf.test_name, 0.06)
            if bound is not None:
                scale = max(float(v.max()), 1e-12)
                assert np.abs(np.diff(v, axis=0)).max() <= bound * scale + 1e-9


def test_poles_are_azimuth_independent(btf):
    """At θ = 0 every azimuth is the same direction: the value must not depend on φ (BTFbase's
    own parameterisation is the exception for the view pole, see docs/conventions.md)."""
    phis = np.linspace(0, 360, 13)
    q = np.column_stack(
        [
            np.full(13, 0.4),
            np.full(13, 0.4),
            np.zeros(13),
            phis,
            np.full(13, 35.0),
            np.full(13, 80.0),
        ]
    )
    v = btf.evaluate_angles(q)
    np.testing.assert_allclose(v, np.broadcast_to(v[0], v.shape), rtol=1e-4, atol=1e-7)


def test_negative_theta_means_the_opposite_azimuth(btf):
    a = btf.evaluate_angles([[0.3, 0.3, -30.0, 10.0, 20.0, 50.0]])
    b = btf.evaluate_angles([[0.3, 0.3, 30.0, 190.0, 20.0, 50.0]])
    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-9)


def test_huge_texture_coordinates_wrap_without_overflow(btf):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        v = btf.evaluate_angles([[1e30, -1e30, 30, 0, 30, 180], [-3.25, 7.5, 30, 0, 30, 180]])
    assert np.all(np.isfinite(v)) and v.min() >= 0


def test_flat_microgeometry_is_lambertian(rng):
    from btf_addon.core.codecs.microgeometry import MicrogeometryBTF

    flat = MicrogeometryBTF(np.zeros((16, 16)), np.full((16, 16, 3), 0.5), 4, "flat")
    n = 2000
    from helpers import random_hemisphere

    wi, wo, uv = random_hemisphere(rng, n), random_hemisphere(rng, n), rng.random((n, 2))
    got = flat.evaluate(uv, wi, wo)
    want = LambertianBTF(0.5).evaluate(uv, wi, wo)
    # Only the soft shadow edge differs, for lights within ~1.5° of the horizon.
    np.testing.assert_allclose(got, want, atol=1e-3)


def test_microgeometry_self_shadows_at_grazing_light():
    bumpy = woven(texels=4, fine_per_texel=8)
    q = np.array([[0.3, 0.3, th, 0.0, 0.0, 0.0] for th in (10.0, 80.0)])
    grazing_ratio = bumpy.evaluate_angles(q)[:, 1]
    lambert_ratio = LambertianBTF(1.0).evaluate_angles(q)[:, 0]
    # Shadowing makes grazing light darker than the cosine alone predicts.
    assert grazing_ratio[1] / grazing_ratio[0] < lambert_ratio[1] / lambert_ratio[0]

"""The analytic material non-BTF objects render with (core/codecs/analytic.py PrincipledBTF),
against
formulas written out here independently: Fujii's Oren-Nayar as printed in the OpenCL ray tracer
seed, the Lambertian and GGX presets it must reduce to, and energy conservation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import random_hemisphere

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF, PrincipledBTF


def _evaluate(btf, wi, wo):
    return btf.evaluate(np.zeros((len(wi), 2)), wi, wo)


def fujii_seed(light, v, rho: float, sigma: float) -> float:
    """The seed's on_diffuse() with n = +z, one query at a time (its sigma_p is our σ).
    Compared at rtol 1e-5 (BTF.evaluate returns float32), atol 1e-6 where two are subtracted."""
    n_l, n_v = light[2], v[2]
    s = float(np.dot(light, v)) - n_l * n_v
    t = max(n_l, n_v) if s >= 0.0 else 1.0
    scoef = math.pi / 2 - 2.0 / 3.0
    a = 1 / (math.pi + scoef * sigma)
    b = sigma / (math.pi + scoef * sigma)
    return rho * n_l * (a + b * (s / t))


@pytest.mark.parametrize("f0", [0.0, 0.04])
def test_diffuse_is_fujiis_oren_nayar_under_the_specular_layer(rng, f0):
    """Diffuse = the seed's Oren-Nayar (σ = 0: Lambertian ρ/π·cos θi) × (1 − Schlick(F0, cos θo)):
    isolated by subtracting the same material with a black base colour (same specular)."""
    wi, wo = random_hemisphere(rng, 500), random_hemisphere(rng, 500)
    for sigma in (0.0, 0.5, 1.0):
        btf = PrincipledBTF(0.7, roughness=0.5, diffuse_roughness=sigma, specular_f0=f0)
        black = PrincipledBTF(0.0, roughness=0.5, diffuse_roughness=sigma, specular_f0=f0)
        diffuse_only = _evaluate(btf, wi, wo) - _evaluate(black, wi, wo)
        want = np.array(
            [
                fujii_seed(a, b, 0.7, sigma) * (1 - (f0 + (1 - f0) * (1 - b[2]) ** 5))
                for a, b in zip(wi, wo, strict=True)
            ]
        )
        np.testing.assert_allclose(diffuse_only[:, 0], want, rtol=1e-5, atol=1e-6)
        if sigma == 0.0:  # and that is Lambertian
            lambert = _evaluate(LambertianBTF(0.7), wi, wo)[:, 0]
            np.testing.assert_allclose(
                want, lambert * (1 - (f0 + (1 - f0) * (1 - wo[:, 2]) ** 5)), rtol=1e-5
            )


def test_a_white_metal_is_the_ggx_preset(rng):
    """Fresnel with F0 = 1 is 1 everywhere and metals have no diffuse part."""
    wi, wo = random_hemisphere(rng, 500), random_hemisphere(rng, 500)
    metal = PrincipledBTF(1.0, roughness=0.4, metallic=1.0)
    np.testing.assert_allclose(
        _evaluate(metal, wi, wo), _evaluate(GGXBTF(1.0, 0.4), wi, wo), rtol=1e-5, atol=1e-9
    )


@pytest.mark.parametrize("metallic", [0.0, 1.0])
@pytest.mark.parametrize("roughness", [0.2, 0.6, 1.0])
def test_reflects_no_more_than_it_receives(rng, metallic, roughness):
    """Directional albedo ∫ value dω ≤ 1 for a white material at every view (Monte Carlo with
    200 k uniform directions; its noise is < 1 %, so the bound allows 2 %)."""
    btf = PrincipledBTF(1.0, roughness, metallic)
    wi = random_hemisphere(rng, 200_000)
    for theta in (0.0, 45.0, 80.0):
        t = math.radians(theta)
        wo = np.tile([math.sin(t), 0.0, math.cos(t)], (len(wi), 1))
        albedo = _evaluate(btf, wi, wo)[:, 0].mean() * 2 * math.pi
        assert 0.0 < albedo < 1.02, (theta, albedo)


def test_parameters_are_validated():
    with pytest.raises(ValueError, match="metallic"):
        PrincipledBTF(0.8, 0.5, metallic=1.5)
    with pytest.raises(ValueError, match="base colour"):
        PrincipledBTF(float("nan"))

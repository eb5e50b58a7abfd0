"""Analytic BTFs, exact at every direction (ground truth for interpolation error).

``LambertianBTF``: value = ρ/π · cos θi — Cycles' Diffuse BSDF.
``GGXBTF``: microfacet GGX without Fresnel, as Cycles' Glossy BSDF (GGX): α = roughness²,
D = α²/(π(1 + (α² − 1)cos²θh)²), height-correlated Smith G = 1/(1 + Λ(ωi) + Λ(ωo)) with
Λ = (−1 + √(1 + α² tan²θ))/2, BRDF = tint·D·G/(4 cos θi cos θo); value = BRDF·cos θi.
``PrincipledBTF``: what non-BTF materials render as (Blender's Principled BSDF inputs base colour,
roughness, metallic, IOR and diffuse roughness), as in the OpenCL ray tracer seed: GGX
Cook-Torrance specular with Schlick's Fresnel (F0 = dielectric F0 mixed towards the base colour by
metallic) plus Fujii's Oren-Nayar diffuse (σ = diffuse roughness; σ = 0 is Lambertian), the
diffuse weighted by (1 − metallic)(1 − F_dielectric(cos θo)) so that energy reflected by the
specular layer is not also diffused. Smith G is the height-correlated one, as for ``GGXBTF``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..model import BTF, BTFMeta, Queries
from .packed import TableWriter, register_codec

#: Below this roughness the GGX lobe is a near-delta that no tabulation or sampler resolves.
MIN_ROUGHNESS = 1e-2


def _rgb(value: Any, what: str) -> np.ndarray:
    rgb = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy()
    if not np.all(np.isfinite(rgb)) or rgb.min() < 0:
        raise ValueError(f"{what} must be finite and non-negative, got {value!r}")
    return rgb


def _analytic_meta(codec: str, tile_size_mm) -> BTFMeta:
    """Analytic BTFs are spatially uniform (one texel) and have no measurement grid."""
    return BTFMeta(
        codec=codec,
        name=codec,
        width=1,
        height=1,
        n_views=0,
        n_lights=0,
        angular_grid="analytic",
        tile_size_mm=tuple(tile_size_mm),
        tile_size_source="analytic: uniform, any size looks the same",
    )


class LambertianBTF(BTF):
    def __init__(self, albedo: Any = 0.8, tile_size_mm: tuple[float, float] = (10.0, 10.0)):
        self.albedo = _rgb(albedo, "albedo")
        self.meta = _analytic_meta("lambertian", tile_size_mm)

    def _evaluate_valid(self, q: Queries) -> np.ndarray:
        return self.albedo[None, :] / np.pi * q.wi[:, 2:3]

    def tables(self) -> dict[str, np.ndarray]:
        return {"albedo": self.albedo.astype(np.float32)}

    def params(self) -> dict[str, Any]:
        return {"albedo": self.albedo.tolist(), "tile_size_mm": list(self.meta.tile_size_mm)}

    @classmethod
    def from_params(cls, params: dict[str, Any], tables: dict[str, np.ndarray]) -> LambertianBTF:
        return cls(params["albedo"], tuple(params["tile_size_mm"]))


#: Cosines are clamped here, identically in Λ and in the 1/(4 cos θo) factor, so that the
#: value tends continuously to its finite grazing limit D/(2α) instead of a 0/0.
MIN_COS = 1e-6


def ggx_lambda(alpha2: float, cos_theta: np.ndarray) -> np.ndarray:
    cos2 = np.maximum(cos_theta, MIN_COS) ** 2
    return 0.5 * (-1.0 + np.sqrt(1.0 + alpha2 * np.maximum(1.0 / cos2 - 1.0, 0.0)))


def ggx_value(wi: np.ndarray, wo: np.ndarray, alpha2: float) -> np.ndarray:
    """(M, 3) unit upper-hemisphere wi, wo → (M,) GGX value D·G/(4 cos θo) (tint 1)."""
    h = wi + wo
    h_len = np.linalg.norm(h, axis=1)
    cos_h = np.where(h_len > 1e-12, h[:, 2] / np.maximum(h_len, 1e-12), 0.0)
    d = alpha2 / (np.pi * (1.0 + (alpha2 - 1.0) * cos_h * cos_h) ** 2)
    g = 1.0 / (1.0 + ggx_lambda(alpha2, wi[:, 2]) + ggx_lambda(alpha2, wo[:, 2]))
    # value = D·G/(4 cos θo): cos θi cancels. At cos θo → 0, G falls like cos θo: finite.
    return np.where(
        (wi[:, 2] >= 0) & (wo[:, 2] >= 0), d * g / (4.0 * np.maximum(wo[:, 2], MIN_COS)), 0.0
    )


class GGXBTF(BTF):
    def __init__(
        self,
        albedo: Any = 0.8,
        roughness: float = 0.3,
        tile_size_mm: tuple[float, float] = (10.0, 10.0),
    ):
        if not np.isfinite(roughness) or not 0.0 <= roughness <= 1.0:
            raise ValueError(f"roughness must be in [0, 1], got {roughness!r}")
        self.albedo = _rgb(albedo, "albedo")
        self.roughness = float(roughness)
        alpha = max(self.roughness, MIN_ROUGHNESS) ** 2
        self.alpha2 = alpha * alpha
        self.meta = _analytic_meta("ggx", tile_size_mm)

    def _evaluate_valid(self, q: Queries) -> np.ndarray:
        return self.albedo[None, :] * ggx_value(q.wi, q.wo, self.alpha2)[:, None]

    def tables(self) -> dict[str, np.ndarray]:
        return {"albedo": self.albedo.astype(np.float32)}

    def params(self) -> dict[str, Any]:
        return {
            "albedo": self.albedo.tolist(),
            "roughness": self.roughness,
            "tile_size_mm": list(self.meta.tile_size_mm),
        }

    @classmethod
    def from_params(cls, params: dict[str, Any], tables: dict[str, np.ndarray]) -> GGXBTF:
        return cls(params["albedo"], params["roughness"], tuple(params["tile_size_mm"]))


def schlick(f0: np.ndarray, cos_theta: np.ndarray) -> np.ndarray:
    """(3,) F0 and (M,) cosines → (M, 3) Schlick Fresnel."""
    c = np.clip(cos_theta, 0.0, 1.0)[:, None]
    return f0[None, :] + (1.0 - f0[None, :]) * (1.0 - c) ** 5


def oren_nayar_fujii(wi: np.ndarray, wo: np.ndarray, sigma: float) -> np.ndarray:
    """(M,) Fujii's improved Oren-Nayar factor, already times cos θi: cos θi·(A + B·s/t).
    cos θi/t ≤ 1 keeps it bounded at grazing angles, where s/t alone grows without limit."""
    ci, co = wi[:, 2], wo[:, 2]
    s = np.sum(wi * wo, axis=1) - ci * co
    t = np.where(s > 0.0, np.maximum(np.maximum(ci, co), MIN_COS), 1.0)
    a = 1.0 / (np.pi + (np.pi / 2 - 2.0 / 3.0) * sigma)
    return a * ci + sigma * a * s * np.where(s > 0.0, ci / t, ci)


class PrincipledBTF(BTF):
    def __init__(
        self,
        base_color: Any = 0.8,
        roughness: float = 0.5,
        metallic: float = 0.0,
        diffuse_roughness: float = 0.0,
        specular_f0: float = 0.04,
        tile_size_mm: tuple[float, float] = (10.0, 10.0),
    ):
        for name, value in (
            ("roughness", roughness),
            ("metallic", metallic),
            ("diffuse_roughness", diffuse_roughness),
            ("specular_f0", specular_f0),
        ):
            if not np.isfinite(value) or not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {value!r}")
        self.base_color = _rgb(base_color, "base colour")
        self.roughness, self.metallic = float(roughness), float(metallic)
        self.diffuse_roughness, self.specular_f0 = float(diffuse_roughness), float(specular_f0)
        alpha = max(self.roughness, MIN_ROUGHNESS) ** 2
        self.alpha2 = alpha * alpha
        self.meta = _analytic_meta("principled", tile_size_mm)

    @property
    def f0(self) -> np.ndarray:
        return self.specular_f0 + (self.base_color - self.specular_f0) * self.metallic

    def _evaluate_valid(self, q: Queries) -> np.ndarray:
        wi, wo = q.wi, q.wo
        h = wi + wo
        h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
        specular = (
            schlick(self.f0, np.sum(h * wo, axis=1)) * ggx_value(wi, wo, self.alpha2)[:, None]
        )
        dielectric = np.full(3, self.specular_f0)
        weight = (1.0 - self.metallic) * (1.0 - schlick(dielectric, wo[:, 2]))
        diffuse = (
            weight * self.base_color * oren_nayar_fujii(wi, wo, self.diffuse_roughness)[:, None]
        )
        return np.where(wi[:, 2:3] >= 0, diffuse + specular, 0.0)

    def tables(self) -> dict[str, np.ndarray]:
        return {"base_color": self.base_color.astype(np.float32)}

    def params(self) -> dict[str, Any]:
        return {
            "base_color": self.base_color.tolist(),
            "roughness": self.roughness,
            "metallic": self.metallic,
            "diffuse_roughness": self.diffuse_roughness,
            "specular_f0": self.specular_f0,
            "tile_size_mm": list(self.meta.tile_size_mm),
        }

    @classmethod
    def from_params(cls, params: dict[str, Any], tables: dict[str, np.ndarray]) -> PrincipledBTF:
        return cls(
            params["base_color"],
            params["roughness"],
            params["metallic"],
            params["diffuse_roughness"],
            params["specular_f0"],
            tuple(params["tile_size_mm"]),
        )


# --- GPU tables (core/codecs/packed.py): parameters in the float header, evaluated by btf_evaluate
# in
# kernels/include/btf_packed.h and shaders/btf_eval_lib.glsl --------------------------------
def _pack_lambertian(btf: LambertianBTF, out: TableWriter) -> None:
    out.set(albedo=btf.albedo)


def _pack_ggx(btf: GGXBTF, out: TableWriter) -> None:
    out.set(albedo=btf.albedo, alpha2=btf.alpha2)


def _pack_principled(btf: PrincipledBTF, out: TableWriter) -> None:
    out.set(
        albedo=btf.base_color,
        alpha2=btf.alpha2,
        metallic=btf.metallic,
        diffuse_roughness=btf.diffuse_roughness,
        specular_f0=btf.specular_f0,
    )


register_codec("lambertian", LambertianBTF, 2, _pack_lambertian)
register_codec("ggx", GGXBTF, 3, _pack_ggx)
register_codec("principled", PrincipledBTF, 5, _pack_principled)

"""The one interface every BTF codec implements.

A BTF value is ``BTF(u, v, θi, φi, θv, φv) → RGB`` in the project's value convention
(docs/conventions.md): **value = apparent BRDF × cos θi**, linear RGB, units 1/sr. A Lambertian
albedo ρ therefore has value ρ/π·cos θi, and a directional light of irradiance E (measured
perpendicular to the light) reflects radiance value·E.

Queries come either as directions in the tangent frame (``evaluate``) or as angles in degrees
(``evaluate_angles``, the BTFbase convention; see core/angles.py). Invalid rows — NaN/Inf
anywhere, zero-length directions, either direction below the horizon (θ > 90°) — give 0.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from .angles import angles_deg_from_directions, directions_from_angles_deg, normalize_directions
from .errors import UnsupportedBTFError

#: Rows evaluated per chunk: bounds temporary memory for 10⁶-query calls.
CHUNK = 1 << 17


@dataclass(frozen=True)
class BTFMeta:
    """Metadata shared by all codecs.

    width, height: texels along u and v. tile_size_mm: physical size (u, v) of one texture
    repeat in millimetres, or None where the source does not state one (BTFbase's text tables,
    a dense table without a size): nothing guesses a size silently; the Blender import asks.
    tile_size_source: where the size came from, in words ("unknown" when None; e.g. "UBO2014
    pixels per mm", "synthetic", "entered at import").
    n_views, n_lights: the measurement (or tabulation) grid sizes; raw_bytes uses them.
    value_scale: factor from the codec's stored units to the value convention.
    """

    codec: str
    name: str
    width: int
    height: int
    n_views: int
    n_lights: int
    angular_grid: str
    hdr: bool = False
    tile_size_mm: tuple[float, float] | None = None
    value_scale: float = 1.0
    extra: dict[str, Any] = field(default_factory=dict)
    tile_size_source: str = "unknown"

    def __post_init__(self) -> None:
        size = self.tile_size_mm
        if size is not None:
            size = (float(size[0]), float(size[1]))
            if not all(np.isfinite(size)) or min(size) <= 0.0:
                raise ValueError(f"tile_size_mm must be two positive sizes, got {size}")
        # frozen: the normalised values go in through object.__setattr__ (dataclass idiom)
        object.__setattr__(self, "tile_size_mm", size)
        if size is None:
            object.__setattr__(self, "tile_size_source", "unknown")
        elif self.tile_size_source == "unknown":
            object.__setattr__(self, "tile_size_source", "stated by the source")

    @property
    def raw_bytes(self) -> int:
        """Size of the uncompressed 8-bit measurement: views × lights × w × h × 3."""
        return self.n_views * self.n_lights * self.width * self.height * 3

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["tile_size_mm"] = None if self.tile_size_mm is None else list(self.tile_size_mm)
        d["raw_bytes"] = self.raw_bytes
        return d


@dataclass
class Queries:
    """Valid query rows in both forms the codecs want.

    uv: (M, 2) float64; wi, wo: (M, 3) unit float64 (light, view) with z ≥ 0;
    theta_i, phi_i, theta_v, phi_v: (M,) degrees, theta in [0, 90], phi in [0, 360).
    """

    uv: np.ndarray
    wi: np.ndarray
    wo: np.ndarray
    theta_i: np.ndarray
    phi_i: np.ndarray
    theta_v: np.ndarray
    phi_v: np.ndarray


class BTF:
    """Base class: input sanitising, chunking and the zero policy live here once."""

    meta: BTFMeta

    # --- what codecs implement -------------------------------------------------------------
    def _evaluate_valid(self, q: Queries) -> np.ndarray:
        """(M,) valid queries → (M, 3) float64 values in the value convention."""
        raise NotImplementedError

    def tables(self) -> dict[str, np.ndarray]:
        """Arrays a GPU back end uploads (and the container stores)."""
        raise NotImplementedError

    def params(self) -> dict[str, Any]:
        """JSON-serialisable parameters that, with ``tables()``, rebuild this BTF."""
        raise NotImplementedError

    # --- public evaluation -------------------------------------------------------------------
    def evaluate(self, uv: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """uv: (N, 2) texture coordinates (wrap); wi, wo: (N, 3) light/view directions in the
        tangent frame (need not be normalised). Returns (N, 3) float32."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        wi, ok_i = normalize_directions(np.asarray(wi).reshape(-1, 3))
        wo, ok_o = normalize_directions(np.asarray(wo).reshape(-1, 3))
        ti, pi = angles_deg_from_directions(wi)
        tv, pv = angles_deg_from_directions(wo)
        valid = ok_i & ok_o & np.all(np.isfinite(uv), axis=1)
        return self._run(valid, uv, wi, wo, ti, pi, tv, pv)

    def evaluate_angles(self, queries: np.ndarray) -> np.ndarray:
        """queries: (N, 6) rows [u, v, θi, φi, θv, φv] in texture units and degrees.
        A negative θ means the direction on the other side: (−θ, φ) ≡ (θ, φ + 180°).
        Returns (N, 3) float32."""
        q = np.asarray(queries, dtype=np.float64).reshape(-1, 6)
        valid = np.all(np.isfinite(q), axis=1)
        q = np.where(valid[:, None], q, 0.0)
        ti, pi = _canonical(q[:, 2], q[:, 3])
        tv, pv = _canonical(q[:, 4], q[:, 5])
        wi = directions_from_angles_deg(ti, pi)
        wo = directions_from_angles_deg(tv, pv)
        return self._run(valid, q[:, :2], wi, wo, ti, pi, tv, pv)

    def raw_units(self, values: np.ndarray, theta_i_deg: np.ndarray) -> np.ndarray:
        """``values`` (N, 3) this BTF gave for light polar angles ``theta_i_deg`` (N,) in the
        codec's stored units, float64: ÷ ``value_scale`` (for MLVQ the original decoder's
        8-bit-scale RGB). A codec whose values carry an angular factor the data lacks undoes
        it too (codecs/svd.py)."""
        return np.asarray(values, dtype=np.float64) / self.meta.value_scale

    def _run(self, valid, uv, wi, wo, ti, pi, tv, pv) -> np.ndarray:
        valid = valid & (ti <= 90.0) & (tv <= 90.0)
        out = np.zeros((len(valid), 3), dtype=np.float32)
        rows = np.flatnonzero(valid)
        for start in range(0, len(rows), CHUNK):
            r = rows[start : start + CHUNK]
            q = Queries(uv[r], wi[r], wo[r], ti[r], pi[r], tv[r], pv[r])
            values = self._evaluate_valid(q)
            # The contract is finite and non-negative whatever a codec's arithmetic did.
            out[r] = np.nan_to_num(np.maximum(values, 0.0), nan=0.0, posinf=0.0)
        return out


class DelegatingBTF(BTF):
    """A BTF evaluated somewhere else (an OpenCL device, GLSL on moderngl or in Blender).

    ``btf``: the wrapped BTF, which supplies ``meta``, ``tables()`` and ``params()`` (so the
    container and the packed layout see the original). ``evaluate_valid``: (M,) valid
    ``Queries`` → (M, 3) values, called per chunk after this base class has sanitised the
    input, so a back end never sees NaN, zero-length or below-horizon rows.
    """

    def __init__(self, btf: BTF, evaluate_valid: Callable[[Queries], np.ndarray]):
        self.btf = btf
        self.meta = btf.meta
        self.evaluator = evaluate_valid

    def _evaluate_valid(self, q: Queries) -> np.ndarray:
        return self.evaluator(q)

    def raw_units(self, values: np.ndarray, theta_i_deg: np.ndarray) -> np.ndarray:
        return self.btf.raw_units(values, theta_i_deg)

    def tables(self) -> dict[str, np.ndarray]:
        return self.btf.tables()

    def params(self) -> dict[str, Any]:
        return self.btf.params()


def innermost(btf: BTF) -> BTF:
    """The BTF under any device wrappers (``DelegatingBTF``): the numpy codec itself."""
    while isinstance(btf, DelegatingBTF):
        btf = btf.btf
    return btf


def _canonical(theta_deg: np.ndarray, phi_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    negative = theta_deg < 0.0
    theta = np.abs(theta_deg)
    phi = np.where(negative, phi_deg + 180.0, phi_deg) % 360.0
    return theta, phi


def tile_size_param(size: tuple[float, float] | None) -> list[float] | None:
    """A tile size as stored in ``params()`` (JSON): a list, or None for unknown."""
    return None if size is None else [float(size[0]), float(size[1])]


def tile_size_from_params(
    params: dict[str, Any], default_source: str = "unknown"
) -> tuple[tuple[float, float] | None, str]:
    """(tile size or None, its source) from ``params()`` as stored. Containers written before
    sizes could be unknown hold a list and no source; their 10 × 10 mm was the old default for
    "not stated", so it reads as unknown."""
    value = params.get("tile_size_mm")
    if value is None:
        return None, "unknown"
    size = (float(value[0]), float(value[1]))
    if "tile_size_source" not in params and size == (10.0, 10.0):
        return None, "unknown"
    return size, params.get("tile_size_source", default_source)


def wrap_texel(uv: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Nearest texel with wrap-around: (M, 2) uv → column x, row y (int64)."""
    # mod first: huge coordinates must not overflow the integer conversion.
    x = np.floor(np.mod(uv[:, 0], 1.0) * width).astype(np.int64) % width
    y = np.floor(np.mod(uv[:, 1], 1.0) * height).astype(np.int64) % height
    return x, y


def box_reduce(texels: np.ndarray, factor: int, name: str) -> np.ndarray:
    """Texels averaged over factor × factor blocks: (H, W, …) → (H // factor, W // factor, …),
    a last partial block dropped (the GPU fallback of a BTF too large for its textures)."""
    h, w = texels.shape[0] // factor, texels.shape[1] // factor
    if h < 1 or w < 1:
        raise UnsupportedBTFError(
            f"{name}: cannot reduce {texels.shape[1]}×{texels.shape[0]} by {factor}"
        )
    blocks = texels[: h * factor, : w * factor]
    return blocks.reshape(h, factor, w, factor, *texels.shape[2:]).mean(axis=(1, 3))

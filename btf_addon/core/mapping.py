"""Where on a BTF tile a surface point looks: UV or Box (triplanar) mapping, real-world size and
bilinear texel filtering — the numpy reference of kernels/include/btf_surface.h (``map_point``,
``btf_mapped``) and shaders/btf_mapping_lib.glsl, which read the same parameter block
(core/codecs/packed.py ``MATERIAL_BLOCK``).

Conventions (all three back ends):
- Texture coordinates = A·s + c (``uv_matrix`` A, ``uv_offset`` c), s the mesh UV (UV mapping)
  or a box projection's 2D coordinates (Box mapping). One tile is one unit; tiles wrap.
- Box mapping works in the box frame q = box_from_world·p: the object's frame with its
  rotation and translation removed but its scale kept as distances (so a box-mapped object is
  stable when it turns or moves and the tile keeps its real size when it is scaled), or the
  world frame. Projection X uses (s·q.y, q.z), Y uses (−s·q.x, q.z), Z uses (s·q.x, q.y), with
  s the sign of the normal's component along that axis, so no face sees its tile mirrored.
  Each projection has its own tangent frame (u along the projection's first coordinate): an
  anisotropic material keeps its direction on every face.
- Box weights from the normal m in the box frame: w_a = clamp((|m_a| − max|m|)/blend + 1, 0, 1),
  normalised (the dominant axis always has 1); blend 0 keeps only the dominant axis (the first
  of equals). Blend is a width in |normal component|: 0.2 blends within ~12° of a cube's edge.
- Bilinear filtering weighs the 4 texels around the point with texel centres at (i + ½)/W,
  wrapping around the tile; each texel is decoded at its centre, so every codec filters the
  same way (four decodes). Nearest decodes once at the point itself. Spatially uniform BTFs
  (analytic: one texel) are never filtered.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .model import BTF

#: The per-material parameter block, one per (mesh, material) draw: how a surface point finds
#: its texture coordinates (``Placement.block`` below computes every value;
#: kernels/include/btf_surface.h and shaders/btf_mapping_lib.glsl read them as ``M_<NAME>``,
#: defines from codecs/packed.py ``defines()``). Values, in order:
#: material: index of the material's packed tables; mapping: MAPPING_UV | MAPPING_BOX;
#: texel_filter: FILTER_LINEAR | FILTER_NEAREST; exposure: the multiplier 2^stops;
#: uv_matrix: 2×2 row-major A and uv_offset c: texture coordinates = A·s + c, where s is the
#: mesh UV (UV mapping) or a box projection's 2D coordinates (Box mapping);
#: box_blend: blend width of the box projection's weights (0 = one projection per point);
#: box_from_world: 3×4 row-major affine map from world space to the box's frame (orthonormal
#: rotation × a uniform scale, so normals map by its 3×3 part then normalise).
MATERIAL_BLOCK: tuple[tuple[str, int], ...] = (
    ("material", 1),
    ("mapping", 1),
    ("texel_filter", 1),
    ("exposure", 1),
    ("uv_matrix", 4),
    ("uv_offset", 2),
    ("box_blend", 1),
    ("box_from_world", 12),
)
MATERIAL_BLOCK_FLOATS = 32  # floats reserved per block (a GLSL texture row, an OpenCL stride)
#: Enumerations of the block, numbered as Blender's EnumProperty items (blender/properties.py
#: ``mapping``, ``texel_filter``): one meaning per number on both sides. They reach device code
#: as defines (MAPPING_*, FILTER_*), so device code never spells a number.
MAPPING_IDS = {"UV": 0, "BOX": 1}
FILTER_IDS = {"LINEAR": 0, "NEAREST": 1}


def _block_slots() -> dict[str, tuple[int, int]]:
    slots, cursor = {}, 0
    for name, size in MATERIAL_BLOCK:
        slots[name] = (cursor, size)
        cursor += size
    return slots


BLOCK_SLOT = _block_slots()  # name → (first float, size)
assert sum(size for _, size in MATERIAL_BLOCK) <= MATERIAL_BLOCK_FLOATS


def material_block(**values: float | Sequence[float]) -> np.ndarray:
    """One parameter block, (MATERIAL_BLOCK_FLOATS,) float32, from values by slot name (every
    slot must be given: a forgotten one would silently read 0 on the device)."""
    missing = set(BLOCK_SLOT) - set(values)
    if missing:
        raise KeyError(f"material block slots missing: {sorted(missing)}")
    out = np.zeros(MATERIAL_BLOCK_FLOATS, dtype=np.float32)
    for name, value in values.items():
        first, size = BLOCK_SLOT[name]  # KeyError for an unknown name
        flat = np.asarray(value, dtype=np.float32).ravel()
        if flat.size != size:
            raise ValueError(f"block slot {name!r} holds {size} floats, got {flat.size}")
        out[first : first + size] = flat
    return out


#: Mapping and filter identifiers as Blender's enum items name them (blender/properties.py).
MAPPINGS = tuple(MAPPING_IDS)
TEXEL_FILTERS = tuple(FILTER_IDS)
#: The texel filter where none is chosen: Blender's property default (blender/properties.py),
#: also for plain-array scenes, so one scene looks the same from every entry point.
DEFAULT_TEXEL_FILTER = "LINEAR"


# --- texel filtering ----------------------------------------------------------------------------
def bilinear_texels(uv: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """uv: (N, 2) texture coordinates (any range) → the 4 surrounding texels' centres
    (N, 4, 2) float64 in [0, 1) and their bilinear weights (N, 4) float64 (sum 1), in the order
    (x0, y0), (x1, y0), (x0, y1), (x1, y1), wrapping around the tile."""
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    size = np.array([width, height], dtype=np.float64)
    # mod first, as the device code: huge coordinates keep their fraction's precision.
    s = (uv - np.floor(uv)) * size - 0.5
    i0 = np.floor(s)
    f = s - i0
    i0 = np.mod(i0, size)
    i1 = np.mod(i0 + 1.0, size)
    xs = np.stack([i0[:, 0], i1[:, 0], i0[:, 0], i1[:, 0]], axis=1)
    ys = np.stack([i0[:, 1], i0[:, 1], i1[:, 1], i1[:, 1]], axis=1)
    centres = np.stack([(xs + 0.5) / width, (ys + 0.5) / height], axis=-1)
    fx, fy = f[:, 0:1], f[:, 1:2]
    weights = np.hstack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])
    return centres, weights


def is_filterable(btf: BTF) -> bool:
    """Whether filtering changes anything: more than one texel (analytic BTFs have one)."""
    return btf.meta.width * btf.meta.height > 1


def filtered_evaluate(
    btf: BTF,
    uv: np.ndarray,
    wi: np.ndarray,
    wo: np.ndarray,
    texel_filter: str = DEFAULT_TEXEL_FILTER,
) -> np.ndarray:
    """``btf.evaluate`` with spatial filtering: uv (N, 2), wi/wo (N, 3) in the tangent frame;
    texel_filter 'LINEAR' (4 decodes at texel centres, bilinear weights) or 'NEAREST' (one
    decode at uv). Returns (N, 3) float32."""
    if texel_filter not in FILTER_IDS:
        raise ValueError(f"texel filter {texel_filter!r}: expected one of {TEXEL_FILTERS}")
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    if texel_filter == "NEAREST" or not is_filterable(btf):
        return btf.evaluate(uv, wi, wo)
    n = len(uv)
    centres, weights = bilinear_texels(uv, btf.meta.width, btf.meta.height)
    wi4 = np.repeat(np.asarray(wi, dtype=np.float64).reshape(-1, 3), 4, axis=0)
    wo4 = np.repeat(np.asarray(wo, dtype=np.float64).reshape(-1, 3), 4, axis=0)
    values = btf.evaluate(centres.reshape(-1, 2), wi4, wo4).astype(np.float64)
    out = np.einsum("nk,nkc->nc", weights, values.reshape(n, 4, 3))
    return out.astype(np.float32)


# --- the parameter block ------------------------------------------------------------------------
def uv_matrix(scale: float, rotation_rad: float, tiles_per_unit=(1.0, 1.0)) -> np.ndarray:
    """(2, 2) A: rotate by ``rotation_rad``, scale by ``scale``, then by tiles per unit along
    the tile's u and v (real-world size: unequal when the tile is not square)."""
    c, s = np.cos(rotation_rad), np.sin(rotation_rad)
    return np.diag(np.asarray(tiles_per_unit, dtype=np.float64)) @ (
        scale * np.array([[c, -s], [s, c]])
    )


def rigid_frame(world_from_object: np.ndarray) -> np.ndarray:
    """(3, 4) box_from_world for object-space box mapping: the inverse of the object's rotation
    and translation, without its scale (distances stay world distances). The rotation is the
    orthonormal polar factor of the 3×3 part (a mirror keeps its reflection)."""
    m = np.asarray(world_from_object, dtype=np.float64)
    u, _, vt = np.linalg.svd(m[:3, :3])
    rotation = u @ vt  # nearest orthogonal matrix (polar decomposition)
    out = np.zeros((3, 4))
    out[:, :3] = rotation.T
    out[:, 3] = -rotation.T @ m[:3, 3]
    return out


def uv_units_per_uv(positions: np.ndarray, uvs: np.ndarray) -> float | None:
    """A mesh's UV density: scene units per UV unit, sqrt(Σ surface area / Σ UV area) over
    its triangles (positions (C, 3) world space, uvs (C, 2), corners = 3 × triangles).
    None when the UVs cover no area (no unwrap, or all collapsed)."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3, 3)
    t = np.asarray(uvs, dtype=np.float64).reshape(-1, 3, 2)
    if len(p) == 0:
        return None
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    uv_area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    ok = np.isfinite(area) & np.isfinite(uv_area)
    total_uv = float(uv_area[ok].sum())
    if total_uv <= 1e-12 * max(float(area[ok].sum()), 1e-30) or total_uv <= 0.0:
        return None
    return float(np.sqrt(area[ok].sum() / total_uv))


@dataclass(frozen=True)
class Placement:
    """What a user sets (blender/properties.py ``material.btf``), bpy-free.

    mapping: 'UV' | 'BOX'; texel_filter: 'LINEAR' | 'NEAREST'; uv_scale: repeats multiplier;
    uv_rotation_rad; uv_offset: (2,) tiles; real_world: size the tile from ``tile_size_mm``;
    tile_size_mm: (u, v) mm or None (unknown: real-world size cannot apply); box_space:
    'OBJECT' | 'WORLD'; box_blend: see the module docstring; exposure: stops.
    """

    mapping: str = "UV"
    texel_filter: str = DEFAULT_TEXEL_FILTER
    uv_scale: float = 1.0
    uv_rotation_rad: float = 0.0
    uv_offset: tuple[float, float] = (0.0, 0.0)
    real_world: bool = False
    tile_size_mm: tuple[float, float] | None = None
    box_space: str = "OBJECT"
    box_blend: float = 0.2
    exposure: float = 0.0

    def __post_init__(self) -> None:
        if self.mapping not in MAPPING_IDS:
            raise ValueError(f"mapping {self.mapping!r}: expected one of {MAPPINGS}")
        if self.texel_filter not in FILTER_IDS:
            raise ValueError(f"texel filter {self.texel_filter!r}: expected {TEXEL_FILTERS}")
        if self.box_space not in ("OBJECT", "WORLD"):
            raise ValueError(f"box space {self.box_space!r}: expected 'OBJECT' or 'WORLD'")

    def tiles_per_metre(self) -> tuple[float, float] | None:
        """Real-world tiles per metre along u and v, or None (off, or size unknown)."""
        if not self.real_world or self.tile_size_mm is None:
            return None
        return 1000.0 / self.tile_size_mm[0], 1000.0 / self.tile_size_mm[1]

    def tile_mm_here(self, units_per_uv: float | None, metres_per_unit: float) -> float | None:
        """For the panel: how many mm one tile spans on a UV-mapped mesh (u direction), or
        None when the mesh has no UV density."""
        if units_per_uv is None:
            return None
        a = self.block_matrix(units_per_uv, metres_per_unit)
        repeats_per_uv = float(np.linalg.norm(a[:, 0]))
        return units_per_uv * metres_per_unit * 1000.0 / max(repeats_per_uv, 1e-30)

    def block_matrix(self, units_per_uv: float | None, metres_per_unit: float) -> np.ndarray:
        """(2, 2) A of the block for a mesh of that UV density (UV) or scene unit (Box)."""
        tiles = self.tiles_per_metre()
        if tiles is None:
            per_unit = (1.0, 1.0)
        elif self.mapping == "UV":
            if units_per_uv is None:
                per_unit = (1.0, 1.0)  # no UV area: nothing to size by; 1 tile per UV square
            else:
                metres = units_per_uv * metres_per_unit
                per_unit = (tiles[0] * metres, tiles[1] * metres)
        else:  # BOX: box coordinates are scene units
            per_unit = (tiles[0] * metres_per_unit, tiles[1] * metres_per_unit)
        return uv_matrix(self.uv_scale, self.uv_rotation_rad, per_unit)

    def block(
        self,
        material_index: int,
        world_from_object: np.ndarray,
        units_per_uv: float | None = None,
        metres_per_unit: float = 1.0,
    ) -> np.ndarray:
        """The parameter block (core/codecs/packed.py) for one mesh drawn with this placement."""
        if self.box_space == "OBJECT":
            box = rigid_frame(world_from_object)
        else:
            box = np.hstack([np.eye(3), np.zeros((3, 1))])
        return material_block(
            material=material_index,
            mapping=MAPPING_IDS[self.mapping],
            texel_filter=FILTER_IDS[self.texel_filter],
            exposure=2.0**self.exposure,
            uv_matrix=self.block_matrix(units_per_uv, metres_per_unit),
            uv_offset=self.uv_offset,
            box_blend=max(self.box_blend, 0.0),
            box_from_world=box,
        )


def read_block(block: np.ndarray) -> dict[str, np.ndarray]:
    """A block's slots by name (float64 arrays), as device code reads them."""
    block = np.asarray(block, dtype=np.float64)
    return {name: block[first : first + size] for name, (first, size) in BLOCK_SLOT.items()}


# --- projections ----------------------------------------------------------------------------------
def box_weights(m: np.ndarray, blend: float) -> np.ndarray:
    """m: (N, 3) normals in the box frame → (N, 3) projection weights summing to 1."""
    a = np.abs(np.asarray(m, dtype=np.float64))
    mx = a.max(axis=1, keepdims=True)
    if blend > 0.0:
        w = np.clip((a - mx) / blend + 1.0, 0.0, 1.0)
    else:
        w = np.zeros_like(a)
        w[np.arange(len(a)), np.argmax(a, axis=1)] = 1.0
    return w / w.sum(axis=1, keepdims=True)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-30)


def _frame_from(n: np.ndarray, along_u: np.ndarray, along_v: np.ndarray):
    """Tangent along ``along_u`` projected onto the plane of n; bitangent on the side of
    ``along_v``. All (N, 3) world space; n unit."""
    t = along_u - n * np.sum(n * along_u, axis=1, keepdims=True)
    tl = np.linalg.norm(t, axis=1, keepdims=True)
    fallback = np.cross(np.where(np.abs(n[:, 2:3]) < 0.9, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]), n)
    t = np.where(tl > 1e-8, t / np.maximum(tl, 1e-30), _unit(fallback))
    b = np.cross(n, t)
    b *= np.where(np.sum(b * along_v, axis=1, keepdims=True) < 0.0, -1.0, 1.0)
    return t, b


@dataclass
class Projection:
    """One of a point's (up to 3) lookups: uv (N, 2) texture coordinates, t/b (N, 3) world
    tangent frame (with the shading normal), weight (N,)."""

    uv: np.ndarray
    t: np.ndarray
    b: np.ndarray
    weight: np.ndarray


def map_points(
    block: np.ndarray,
    p: np.ndarray,
    n: np.ndarray,
    t: np.ndarray,
    b: np.ndarray,
    uv: np.ndarray,
) -> list[Projection]:
    """Surface points → their projections. p: (N, 3) world positions; n: (N, 3) unit shading
    normal (facing the viewer); t, b: (N, 3) the mesh's UV tangent frame; uv: (N, 2) mesh UVs.
    UV mapping gives one projection (the mesh frame), Box mapping three (weights may be 0)."""
    k = read_block(block)
    a = k["uv_matrix"].reshape(2, 2)
    c = k["uv_offset"]
    p, n = np.asarray(p, np.float64), np.asarray(n, np.float64)
    if int(k["mapping"][0]) == MAPPING_IDS["UV"]:
        tex = np.asarray(uv, np.float64) @ a.T + c
        return [
            Projection(tex, np.asarray(t, np.float64), np.asarray(b, np.float64), np.ones(len(p)))
        ]
    box = k["box_from_world"].reshape(3, 4)
    q = p @ box[:, :3].T + box[:, 3]
    m = _unit(n @ box[:, :3].T)
    w = box_weights(m, float(k["box_blend"][0]))
    sign = np.where(m >= 0.0, 1.0, -1.0)
    zero = np.zeros(len(p))
    one = np.ones(len(p))
    coords = (
        np.stack([sign[:, 0] * q[:, 1], q[:, 2]], axis=1),
        np.stack([-sign[:, 1] * q[:, 0], q[:, 2]], axis=1),
        np.stack([sign[:, 2] * q[:, 0], q[:, 1]], axis=1),
    )
    along_u = (
        np.stack([zero, sign[:, 0], zero], axis=1),
        np.stack([-sign[:, 1], zero, zero], axis=1),
        np.stack([sign[:, 2], zero, zero], axis=1),
    )
    along_v = (
        np.stack([zero, zero, one], axis=1),
        np.stack([zero, zero, one], axis=1),
        np.stack([zero, one, zero], axis=1),
    )
    out = []
    for axis in range(3):
        # box frame → world: the transpose of the orthonormal (scaled) 3×3 part
        tw, bw = _frame_from(n, along_u[axis] @ box[:, :3], along_v[axis] @ box[:, :3])
        out.append(Projection(coords[axis] @ a.T + c, tw, bw, w[:, axis]))
    return out


def mapped_evaluate(
    btf: BTF,
    block: np.ndarray,
    p: np.ndarray,
    n: np.ndarray,
    t: np.ndarray,
    b: np.ndarray,
    uv: np.ndarray,
    wi: np.ndarray,
    wo: np.ndarray,
) -> np.ndarray:
    """The value a renderer gets at surface points (exposure not applied): ``map_points`` then
    per projection the filtered lookup with wi/wo (N, 3) world directions expressed in that
    projection's frame. Returns (N, 3) float32."""
    texel_filter = TEXEL_FILTERS[int(read_block(block)["texel_filter"][0])]
    wi, wo = np.asarray(wi, np.float64), np.asarray(wo, np.float64)
    n = np.asarray(n, np.float64)
    out = np.zeros((len(wi), 3))
    for proj in map_points(block, p, n, t, b, uv):
        use = proj.weight > 0.0
        if not use.any():
            continue

        def frame(d, proj=proj, use=use):
            return np.stack(
                [
                    np.sum(d[use] * proj.t[use], axis=1),
                    np.sum(d[use] * proj.b[use], axis=1),
                    np.sum(d[use] * n[use], axis=1),
                ],
                axis=1,
            )

        values = filtered_evaluate(btf, proj.uv[use], frame(wi), frame(wo), texel_filter)
        out[use] += proj.weight[use, None] * values
    return out.astype(np.float32)

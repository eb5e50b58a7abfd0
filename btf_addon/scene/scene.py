"""A renderable scene as plain arrays: what the Blender layer exports and every renderer draws.

Frames are named by what they map (pbrt's habit): ``world_from_object`` takes object-space
points to world space. World space is Blender's: Z up, metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.mapping import DEFAULT_TEXEL_FILTER, MATERIAL_BLOCK_FLOATS, Placement, uv_units_per_uv
from ..core.model import BTF
from ..core.sampling.envmap import Environment
from .lights import Light


@dataclass
class Material:
    """A BTF with its placement on the surface (core/mapping.py documents each choice).

    uv_scale: texture repeats per UV unit (× the real-world factor when on); uv_rotation_rad:
    rotation in UV space; uv_offset: (2,) tiles; exposure: brightness in stops
    (value × 2^exposure); mapping: 'UV' | 'BOX'; texel_filter: 'LINEAR' | 'NEAREST' (the
    default is Blender's property's, core/mapping.py ``DEFAULT_TEXEL_FILTER``);
    real_world: size the tile from its physical size; tile_size_mm: (u, v) mm overriding the
    BTF's own (None: use ``btf.meta.tile_size_mm``, which may itself be unknown);
    box_space: 'OBJECT' | 'WORLD'; box_blend: blend width of the box projections.
    """

    btf: BTF
    uv_scale: float = 1.0
    uv_rotation_rad: float = 0.0
    exposure: float = 0.0
    name: str = ""
    mapping: str = "UV"
    texel_filter: str = DEFAULT_TEXEL_FILTER
    uv_offset: tuple[float, float] = (0.0, 0.0)
    real_world: bool = False
    tile_size_mm: tuple[float, float] | None = None
    box_space: str = "OBJECT"
    box_blend: float = 0.2

    @property
    def physical_size_mm(self) -> tuple[float, float] | None:
        """The tile size used for real-world mapping: this material's, else the BTF's."""
        return self.tile_size_mm if self.tile_size_mm is not None else self.btf.meta.tile_size_mm

    def placement(self) -> Placement:
        return Placement(
            mapping=self.mapping,
            texel_filter=self.texel_filter,
            uv_scale=self.uv_scale,
            uv_rotation_rad=self.uv_rotation_rad,
            uv_offset=tuple(self.uv_offset),
            real_world=self.real_world,
            tile_size_mm=self.physical_size_mm,
            box_space=self.box_space,
            box_blend=self.box_blend,
            exposure=self.exposure,
        )

    def block(self, index: int, mesh: Mesh, metres_per_unit: float = 1.0) -> np.ndarray:
        """The parameter block (core/codecs/packed.py MATERIAL_BLOCK) for ``mesh`` drawn with this
        material, which is ``index`` in the scene: (MATERIAL_BLOCK_FLOATS,) float32."""
        units = mesh.units_per_uv() if self.mapping == "UV" and self.real_world else None
        return self.placement().block(index, mesh.world_from_object, units, metres_per_unit)


@dataclass
class Mesh:
    """Triangles in object space with per-corner attributes (corners = 3 × triangles).

    positions: (C, 3) float32; normals: (C, 3) float32 unit; uvs: (C, 2) float32;
    tangents: (C, 4) float32 — unit tangent along +u and the bitangent sign (±1), as MikkTSpace;
    world_from_object: (4, 4) float64; material: index into Scene.materials.
    """

    positions: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    tangents: np.ndarray
    world_from_object: np.ndarray = field(default_factory=lambda: np.eye(4))
    material: int = 0
    name: str = ""

    @property
    def triangle_count(self) -> int:
        return len(self.positions) // 3

    def units_per_uv(self) -> float | None:
        """UV density in world units per UV unit (object scale included), computed once per
        mesh and world matrix (core/mapping.py ``uv_units_per_uv``); None without UV area."""
        key = np.asarray(self.world_from_object, dtype=np.float64).tobytes()
        cached = self.__dict__.get("_units_per_uv")
        if cached is None or cached[0] != key:
            m = np.asarray(self.world_from_object, dtype=np.float64)
            p = np.asarray(self.positions, dtype=np.float64) @ m[:3, :3].T
            cached = (key, uv_units_per_uv(p, self.uvs))
            self.__dict__["_units_per_uv"] = cached
        return cached[1]

    def world_space_corners(self) -> np.ndarray:
        """(corners, 12) float32 rows: position, normal, uv, tangent and bitangent sign, in
        world space, for drawing. Triangles with any non-finite value are dropped."""
        m = np.asarray(self.world_from_object, dtype=np.float64)
        a = m[:3, :3]
        p = self.positions @ a.T + m[:3, 3]
        finite = bool(np.all(np.isfinite(a)))
        det = np.linalg.det(a) if finite else np.nan
        if not finite:  # every triangle is dropped below
            n = np.full(self.normals.shape, np.nan)
        elif det != 0.0:
            n = self.normals @ np.linalg.inv(a)  # (M^-1)^T applied to row vectors
        else:
            # A scale of 0 (Blender allows it) has no inverse: taken as the limit of a tiny
            # scale, its zero singular values raised to 1e-9 of the largest (a flattened
            # object's normals turn to its plane's, as they would at scale 1e-9).
            u, sv, vt = np.linalg.svd(a)
            sv = np.maximum(sv, max(sv.max() * 1e-9, 1e-30)) if sv.max() > 0 else np.ones(3)
            n = self.normals @ (vt.T / sv) @ u.T
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        t = self.tangents[:, :3] @ a.T
        # A mirroring transform (negative determinant) flips the bitangent's handedness.
        sign = self.tangents[:, 3:4] * (np.sign(det) or 1.0)
        with np.errstate(invalid="ignore"):
            data = np.hstack([p, n, self.uvs, t, sign]).astype(np.float32)
        ok = np.all(np.isfinite(data), axis=1).reshape(-1, 3).all(axis=1)
        return data.reshape(-1, 3, 12)[ok].reshape(-1, 12)


@dataclass
class Camera:
    """world_from_camera: (4, 4); the camera looks along its −Z with +Y up (Blender's).
    perspective: vertical field of view (radians); orthographic: ortho_scale is the larger side."""

    world_from_camera: np.ndarray
    perspective: bool = True
    fov_y_rad: float = np.radians(40.0)
    ortho_scale: float = 6.0
    clip_start: float = 0.01
    clip_end: float = 1000.0
    shift: tuple[float, float] = (0.0, 0.0)

    def frustum(self, aspect: float) -> tuple[float, float, float, float]:
        """(left, right, bottom, top) at the near plane (perspective) or in camera units
        (orthographic), with Blender's shift: 1.0 moves the frame by its larger dimension."""
        if self.perspective:
            top = self.clip_start * np.tan(self.fov_y_rad / 2)
        else:
            top = self.ortho_scale / 2 / max(aspect, 1.0)
        right = top * aspect
        big = 2 * max(right, top)
        dx, dy = self.shift[0] * big, self.shift[1] * big
        return -right + dx, right + dx, -top + dy, top + dy

    def projection(self, aspect: float) -> np.ndarray:
        """OpenGL clip_from_camera (4, 4) for width/height = ``aspect``."""
        n, f = self.clip_start, self.clip_end
        l_, r, b, t = self.frustum(aspect)
        if self.perspective:
            return np.array(
                [
                    [2 * n / (r - l_), 0, (r + l_) / (r - l_), 0],
                    [0, 2 * n / (t - b), (t + b) / (t - b), 0],
                    [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)],
                    [0, 0, -1, 0],
                ]
            )
        return np.array(
            [
                [2 / (r - l_), 0, 0, -(r + l_) / (r - l_)],
                [0, 2 / (t - b), 0, -(t + b) / (t - b)],
                [0, 0, -2 / (f - n), -(f + n) / (f - n)],
                [0, 0, 0, 1],
            ]
        )

    @property
    def position(self) -> np.ndarray:
        return self.world_from_camera[:3, 3]

    def clip_from_world(self, aspect: float) -> np.ndarray:
        return self.projection(aspect) @ np.linalg.inv(self.world_from_camera)

    def shader_vector(self) -> np.ndarray:
        """What the surface shaders call ``camera``: (position, 1) for perspective views, or
        (direction towards the viewer, 0) for orthographic ones."""
        if self.perspective:
            return np.array([*self.position, 1.0], dtype=np.float32)
        return np.array([*self.world_from_camera[:3, 2], 0.0], dtype=np.float32)


@dataclass
class Scene:
    meshes: list[Mesh]
    materials: list[Material]
    camera: Camera
    environment: Environment
    messages: list[str] = field(default_factory=list)
    lights: list[Light] = field(default_factory=list)  # Blender lights: scene/lights.py
    metres_per_unit: float = 1.0  # Blender's Unit Scale: what real-world sizes measure in
    #: The light bake the drawer plays back (render/light_bake.py ``LightBake``; None: none).
    #: Typed loosely: this layer does not import render/.
    light_bake: Any = None

    def material_blocks(self) -> np.ndarray:
        """(len(meshes), MATERIAL_BLOCK_FLOATS) float32: one parameter block per mesh (its
        material's placement on that mesh), row i for ``meshes[i]``."""
        rows = [
            self.materials[mesh.material].block(mesh.material, mesh, self.metres_per_unit)
            for mesh in self.meshes
        ]
        if not rows:
            return np.zeros((1, MATERIAL_BLOCK_FLOATS), dtype=np.float32)
        return np.stack(rows)


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """world_from_camera for a camera at ``eye`` looking at ``target`` (−Z forward, +Y up)."""
    eye, target, up = (np.asarray(v, dtype=np.float64) for v in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    if np.linalg.norm(right) < 1e-9:  # looking straight up or down: any perpendicular will do
        right = np.cross((0.0, 1.0, 0.0), back)
    right /= np.linalg.norm(right)
    true_up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, true_up, back, eye
    return m

"""Which effects a scene calls for, so the final render builds kernels with only those paths.

Shadows: a ray towards a light can only be blocked by geometry. With a single convex mesh no
point of it can shadow another (a point's own side facing away from the light is already dark
by n·l), so shadow rays are skipped; any second mesh, or a non-convex one, turns them on.
The same argument holds for point and area lights outside the mesh. Each light type's code
(sun; point and spot; area) is compiled only when the scene has such a light; each codec's
decoder (MLVQ; dense; svd; the analytic ones) only when a material uses it; a black World
compiles no environment sampling. The result becomes ``-D`` defines.

Variants: a scene needs exactly one program (every final-render kernel is in it), cached on
disk by its define set (cl/programs.py). There are 9 yes/no defines (shadows, 3 light types,
environment, 4 codec families), so at most 2^9 = 512 variants exist, 480 with at least one
codec; a user compiles only those their scenes need (one per scene). docs/accuracy.md
"Specialisation" measures what each one saves.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry_cache import cached_verdict
from .lights import AreaLight, PointLight, SunLight
from .scene import Scene

#: Codec name → the define compiling its decoder (kernels/include/btf_packed.h).
CODEC_DEFINES = {
    "mlvq": "HAS_MLVQ",
    "dense": "HAS_DENSE",
    "svd": "HAS_SVD",
    "lambertian": "HAS_ANALYTIC",
    "ggx": "HAS_ANALYTIC",
    "principled": "HAS_ANALYTIC",
}
ALL_CODECS = frozenset(CODEC_DEFINES)

#: How far (× the mesh's size) a vertex may lie in front of a face's plane in a convex mesh.
CONVEX_TOLERANCE = 1e-4
#: Above this many face × vertex tests, convexity is not checked and shadows stay on.
MAX_CONVEXITY_WORK = 50_000_000
#: Vertex × plane products per block of is_convex: 16 MB of float32 at a time.
CONVEXITY_BLOCK = 1 << 22


@dataclass(frozen=True)
class SceneFeatures:
    """What the scene calls for. The defaults compile everything (the unspecialised program):
    a caller that builds features by hand gets correct, if slower, kernels."""

    shadows: bool
    environment_texture: bool
    area_lights: bool = True
    sun_lights: bool = True
    point_lights: bool = True  # point and spot
    environment: bool = True  # False: a black World
    codecs: frozenset[str] = ALL_CODECS

    def defines(self) -> dict[str, int]:
        out = {
            "HAS_SHADOWS": int(self.shadows),
            "HAS_AREA_LIGHTS": int(self.area_lights),
            "HAS_SUN_LIGHTS": int(self.sun_lights),
            "HAS_POINT_LIGHTS": int(self.point_lights),
            "HAS_ENVIRONMENT": int(self.environment),
        }
        unknown = self.codecs - ALL_CODECS  # a codec without its own define: compile all
        for define in sorted(set(CODEC_DEFINES.values())):
            wanted = {c for c, d in CODEC_DEFINES.items() if d == define}
            out[define] = int(bool(unknown) or bool(self.codecs & wanted))
        return out


def is_convex(corners: np.ndarray, tolerance: float = CONVEX_TOLERANCE) -> bool:
    """corners: (3·T, ≥3) world-space positions in the first 3 columns. True when no vertex lies
    more than ``tolerance`` × the mesh's size in front of any face's plane."""
    p = corners[:, :3].astype(np.float64).reshape(-1, 3, 3)
    if len(p) == 0:
        return True
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(normals, axis=1)
    keep = length > 1e-20
    normals, origins = normals[keep] / length[keep, None], p[keep, 0]
    corners = np.ascontiguousarray(p.reshape(-1, 3))
    # Each vertex once (a vertex is a corner of ~6 triangles): unique rows compared as 24-byte
    # strings, several times faster than np.unique(axis=0). (-0.0 and 0.0 stay apart: harmless.)
    _, first = np.unique(corners.view(np.dtype((np.void, 24))), return_index=True)
    points = corners[first]
    if len(normals) * len(points) > MAX_CONVEXITY_WORK:
        return False
    low, high = points.min(axis=0), points.max(axis=0)
    scale = max(float((high - low).max()), 1e-12)
    # Every vertex against every plane is one float32 matrix product per block of planes (in
    # homogeneous coordinates: [p, 1] · [n, −n·o]): a fraction of the float64 arithmetic's
    # time, which was a visible part of a small scene's F12. Coordinates are taken relative to
    # the mesh's centre and in units of its size, so float32's rounding (~1e-7) stays far below
    # the tolerance (1e-4) wherever the mesh sits in the world.
    centre = (low + high) / 2
    homogeneous = np.ones((len(points), 4), dtype=np.float32)
    homogeneous[:, :3] = (points - centre) / scale
    offsets = np.einsum("ij,ij->i", normals, (origins - centre) / scale)
    planes = np.concatenate([normals, -offsets[:, None]], axis=1).astype(np.float32).T
    block = max(1, CONVEXITY_BLOCK // len(points))  # bounds the product's memory
    for start in range(0, planes.shape[1], block):
        if (homogeneous @ planes[:, start : start + block]).max() > tolerance:
            return False
    return True


def _convex(corners: np.ndarray) -> bool:
    """is_convex, from the disk when this mesh was judged before (geometry_cache.py)."""
    question = {"what": "convex", "tolerance": CONVEX_TOLERANCE}
    return cached_verdict(corners, question, lambda: is_convex(corners))


def analyse(scene: Scene) -> SceneFeatures:
    meshes = [m.world_space_corners() for m in scene.meshes]
    meshes = [m for m in meshes if len(m)]
    shadows = len(meshes) > 1 or (len(meshes) == 1 and not _convex(meshes[0]))
    env = scene.environment
    return SceneFeatures(
        shadows=shadows,
        environment_texture=env.width * env.height > 1,
        area_lights=any(isinstance(light, AreaLight) for light in scene.lights),
        sun_lights=any(isinstance(light, SunLight) for light in scene.lights),
        point_lights=any(isinstance(light, PointLight) for light in scene.lights),
        environment=not env.is_black,
        codecs=frozenset(m.btf.meta.codec for m in scene.materials),
    )

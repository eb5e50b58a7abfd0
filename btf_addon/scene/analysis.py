"""Which effects a scene calls for, so the final render builds kernels with only those paths.

Shadows: a ray towards a light can only be blocked by geometry. With a single convex mesh no
point of it can shadow another (a point's own side facing away from the light is already dark
by n·l), so shadow rays are skipped; any second mesh, or a non-convex one, turns them on.
The same argument holds for point and area lights outside the mesh. Area-light sampling is
compiled only when the scene has an area light. The result becomes ``-D`` defines (few
variants: BlendLuxCore's users' first complaint).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lights import AreaLight
from .scene import Scene

#: Above this many face × vertex tests, convexity is not checked and shadows stay on.
MAX_CONVEXITY_WORK = 50_000_000


@dataclass(frozen=True)
class SceneFeatures:
    shadows: bool
    environment_texture: bool
    area_lights: bool = False

    def defines(self) -> dict[str, int]:
        return {"HAS_SHADOWS": int(self.shadows), "HAS_AREA_LIGHTS": int(self.area_lights)}


def is_convex(corners: np.ndarray, tolerance: float = 1e-4) -> bool:
    """corners: (3·T, ≥3) world-space positions in the first 3 columns."""
    p = corners[:, :3].astype(np.float64).reshape(-1, 3, 3)
    if len(p) == 0:
        return True
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(normals, axis=1)
    keep = length > 1e-20
    normals, origins = normals[keep] / length[keep, None], p[keep, 0]
    points = np.unique(p.reshape(-1, 3), axis=0)
    if len(normals) * len(points) > MAX_CONVEXITY_WORK:
        return False
    scale = max(float(np.ptp(points, axis=0).max()), 1e-12)
    for start in range(0, len(normals), 256):
        n, o = normals[start : start + 256], origins[start : start + 256]
        side = points @ n.T - np.sum(n * o, axis=1)
        if side.max() > tolerance * scale:
            return False
    return True


def analyse(scene: Scene) -> SceneFeatures:
    meshes = [m.world_space_corners() for m in scene.meshes]
    meshes = [m for m in meshes if len(m)]
    shadows = len(meshes) > 1 or (len(meshes) == 1 and not is_convex(meshes[0]))
    env = scene.environment
    return SceneFeatures(
        shadows=shadows,
        environment_texture=env.width * env.height > 1,
        area_lights=any(isinstance(light, AreaLight) for light in scene.lights),
    )

"""Which eye a draw is for, from nothing but its matrices (and the viewer pose when known).

Blender's VR session runs the 'XR' POST_VIEW draw callbacks once per eye per frame without
saying which eye (wm_xr_draw.cc passes no view index), yet each eye needs its own progressive
accumulation. The rule, in order:

1. Viewer pose known (the session's ``viewer_pose_location``: the point between the eyes):
   the eye's offset from it along the eye's own view-space +x (its "right" axis in world
   space). Negative: ``"left"``, positive: ``"right"``, within ``MONO_TOLERANCE`` of zero:
   ``"mono"`` (a mirror window or a single-view runtime).
2. Otherwise the projection's horizontal skew, ``clip_from_view[0, 2]`` = (r + l) / (r − l)
   with l = tan(angle_left) < 0 < r = tan(angle_right): a headset eye's frustum reaches further
   outwards (away from the nose) than inwards, so the left eye's skew is negative and the right
   eye's positive.
3. Otherwise (a symmetric frustum and no pose: a test's or another tool's own eye matrices):
   the eye's position. The first two positions more than ``SAME_EYE_M`` apart get ``"eye-0"``
   and ``"eye-1"``; every later draw goes to the nearer of the two.

``offset`` (world units from the head centre along the eye's +x, negative for the left eye) is
what the stereo HUD needs to fix its quad to the head rather than to each eye; in case 2 and 3
it is unknown and 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.mat4 import inverse

MONO_TOLERANCE = 1e-6  # relative to the eye's distance from the origin (float32 positions)
SKEW_TOLERANCE = 1e-6
SAME_EYE_M = 0.01  # two positions this close are one eye (eyes are ~0.064 m apart)


@dataclass(frozen=True)
class EyeId:
    key: str  # "left" | "right" | "mono" | "eye-0" | "eye-1"
    offset: float  # along the eye's +x from the head centre, world units; 0 when unknown
    rule: str  # "viewer pose" | "projection skew" | "position"


@dataclass
class EyeIdentifier:
    """Keeps the positions rule 3 needs between calls; rules 1 and 2 need no memory."""

    positions: dict[str, np.ndarray] = field(default_factory=dict)

    def identify(
        self,
        view_from_world: np.ndarray,
        clip_from_view: np.ndarray,
        viewer_location: np.ndarray | None = None,
    ) -> EyeId:
        world_from_view = inverse(view_from_world)
        eye, right = world_from_view[:3, 3], world_from_view[:3, 0]
        right = right / np.linalg.norm(right)
        if viewer_location is not None:
            offset = float(np.dot(eye - np.asarray(viewer_location, dtype=np.float64), right))
            if abs(offset) <= MONO_TOLERANCE * max(1.0, float(np.linalg.norm(eye))):
                return EyeId("mono", 0.0, "viewer pose")
            return EyeId("left" if offset < 0 else "right", offset, "viewer pose")
        skew = float(np.asarray(clip_from_view)[0, 2])
        if abs(skew) > SKEW_TOLERANCE:
            return EyeId("left" if skew < 0 else "right", 0.0, "projection skew")
        return EyeId(self._by_position(eye), 0.0, "position")

    def _by_position(self, eye: np.ndarray) -> str:
        distances = {k: float(np.linalg.norm(eye - p)) for k, p in self.positions.items()}
        if len(self.positions) < 2 and all(d > SAME_EYE_M for d in distances.values()):
            key = f"eye-{len(self.positions)}"
        else:
            key = min(distances, key=distances.get)
        self.positions[key] = eye.copy()
        return key

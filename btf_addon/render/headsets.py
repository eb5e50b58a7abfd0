"""Headset profiles and stereo maths in OpenXR's conventions, bpy-free.

A profile holds what a runtime reports for a headset (per-eye resolution and field of view,
IPD, refresh rate) so that tests and benchmarks can build the two eyes of a session without
one: the per-eye projection exactly as OpenXR's ``XrMatrix4x4f_CreateProjectionFov`` builds it
for OpenGL (and as Blender's ``perspective_m4_fov`` does from the same four tangents), and the
eyes' views offset by ∓IPD/2 along the head's +x, looking down the head's −z (OpenXR's view
space and Blender's camera space share these axes: +x right, +y up, −z forward).
When a runtime reports its own numbers, prefer them: these are for planning and tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class EyeFov:
    """An eye's field of view in radians, OpenXR's XrFovf: the angles of the frustum's four
    sides from the view direction, ``angle_left`` < ``angle_right`` and ``angle_down`` <
    ``angle_up`` (usually angle_left < 0 < angle_right, angle_down < 0 < angle_up)."""

    angle_left: float
    angle_right: float
    angle_up: float
    angle_down: float

    def __post_init__(self) -> None:
        half_pi = math.pi / 2
        angles = (self.angle_left, self.angle_right, self.angle_up, self.angle_down)
        if not all(-half_pi < a < half_pi for a in angles):
            raise ValueError(f"FOV angles must lie strictly within ±π/2 rad, got {angles}")
        if not (self.angle_left < self.angle_right and self.angle_down < self.angle_up):
            raise ValueError(f"need angle_left < angle_right and angle_down < angle_up: {self}")

    @classmethod
    def from_tangents(cls, left: float, right: float, up: float, down: float) -> EyeFov:
        """From the tangents of the four angles (OpenVR's raw projection values)."""
        return cls(math.atan(left), math.atan(right), math.atan(up), math.atan(down))

    def mirrored(self) -> EyeFov:
        """The other eye's field of view, mirrored left/right."""
        return replace(self, angle_left=-self.angle_right, angle_right=-self.angle_left)


@dataclass(frozen=True)
class HeadsetProfile:
    """A headset as a runtime would report it. ``eye_width`` × ``eye_height``: pixels per
    eye (the recommended render size); ``ipd_m``: metres; ``source``: where the numbers come
    from and which are nominal."""

    name: str
    label: str
    eye_width: int
    eye_height: int
    fov_left_eye: EyeFov
    fov_right_eye: EyeFov
    ipd_m: float
    refresh_hz: float
    source: str

    def __post_init__(self) -> None:
        if self.eye_width < 1 or self.eye_height < 1:
            raise ValueError(f"{self.name}: eye size {self.eye_width}×{self.eye_height}")
        if not self.refresh_hz > 0 or self.ipd_m < 0:
            raise ValueError(f"{self.name}: refresh {self.refresh_hz} Hz, IPD {self.ipd_m} m")

    @property
    def frame_budget_s(self) -> float:
        """Seconds per frame at the refresh rate: what one stereo frame may take."""
        return 1.0 / self.refresh_hz

    def scaled(self, factor: float) -> HeadsetProfile:
        """The same headset at ``factor`` times the per-eye resolution (each side rounded,
        at least 1 pixel); FOV, IPD and refresh unchanged. For tests and benchmarks."""
        if not factor > 0:
            raise ValueError(f"scale factor must be positive, got {factor}")
        return replace(
            self,
            eye_width=max(1, round(self.eye_width * factor)),
            eye_height=max(1, round(self.eye_height * factor)),
        )


def _fov_deg(left: float, right: float, up: float, down: float) -> EyeFov:
    return EyeFov(*(math.radians(a) for a in (left, right, up, down)))


# The XTAL panels are 16:9; with square pixels the tangents of the horizontal FOV must sum to
# 16/9 of the vertical ones. Nominal per-eye frustum: ±45° vertically (tangent sum 2), 45°
# towards the nose and atan(32/9 − 1) ≈ 68.6° outwards (tangent sum 32/9): 137° binocular.
_XTAL_OUTER = math.degrees(math.atan(32 / 9 - 1))
_XTAL_LEFT_EYE = _fov_deg(-_XTAL_OUTER, 45.0, 45.0, -45.0)
# HTC Vive's left eye as SteamVR reports it (hmdq, risa2000's HMD geometry database, raw
# tangents): its 0.90 width/height matches a 2016×2240 render target with square pixels.
_VIVE_LEFT_EYE = EyeFov.from_tangents(-1.397283, 1.250510, 1.464221, -1.477517)
_VIVE_RIGHT_EYE = EyeFov.from_tangents(-1.247887, 1.394608, 1.460934, -1.475235)
_SIMULATED_EYE = EyeFov(-0.74, 0.74, 0.78, -0.78)

PROFILES: dict[str, HeadsetProfile] = {
    p.name: p
    for p in (
        HeadsetProfile(
            "xtal-8k",
            "VRgineers XTAL 8K",
            3840,
            2160,
            _XTAL_LEFT_EYE,
            _XTAL_LEFT_EYE.mirrored(),
            0.064,
            75.0,
            "Two 3840×2160 LCD panels, one per eye: the manufacturer's figure quoted in the BTF "
            "VR thesis (DESIGN.md). Nominal, not from a runtime: 75 Hz refresh (vendor "
            "marketing, not checked here), IPD 64 mm (the XTAL's automatic IPD spans 56–74 mm, "
            "VRgineers' user guide), and the per-eye frustum: ±45° vertically, 45° nasal and "
            "68.6° temporal so that the 16:9 panel has square pixels (the vendor's 180° "
            "horizontal figure needs canted views, which these parallel eyes do not model).",
        ),
        HeadsetProfile(
            "xtal-3",
            "VRgineers XTAL 3",
            3840,
            2160,
            _XTAL_LEFT_EYE,
            _XTAL_LEFT_EYE.mirrored(),
            0.064,
            120.0,
            "Nominal throughout: 3840×2160 per eye at 120 Hz as the vendor advertises it "
            "(not checked here); the XTAL 8K's nominal frustum and 64 mm IPD (the XTAL 3's "
            "lenses move over 60–74 mm, VRgineers' user guide).",
        ),
        HeadsetProfile(
            "generic-2016x2240",
            "Generic PC headset, 2016×2240 per eye, 90 Hz",
            2016,
            2240,
            _VIVE_LEFT_EYE,
            _VIVE_RIGHT_EYE,
            0.064,
            90.0,
            "A typical SteamVR render target (1.4× per side of a 1440×1600 panel) at 90 Hz; "
            "per-eye FOV of an HTC Vive as SteamVR reports it (hmdq record in risa2000's HMD "
            "geometry database); IPD 64 mm nominal.",
        ),
        HeadsetProfile(
            "simulated",
            "Simulated OpenXR HMD (Monado)",
            320,
            240,
            _SIMULATED_EYE,
            _SIMULATED_EYE,
            0.063,
            20.0,
            "What Monado's simulated HMD reported on these machines (DESIGN.md): 320×240 per "
            "eye recommended, FOV about ±0.74 rad horizontally and ±0.78 rad vertically, "
            "frames paced at 20 Hz. IPD 63 mm nominal (not recorded).",
        ),
    )
}


def profile(name: str) -> HeadsetProfile:
    """The profile called ``name``; ValueError listing the known names otherwise."""
    try:
        return PROFILES[name]
    except KeyError:
        known = ", ".join(sorted(PROFILES))
        raise ValueError(f"unknown headset profile {name!r}; known: {known}") from None


def projection_from_fov(fov: EyeFov, near: float, far: float) -> np.ndarray:
    """(4, 4) float64 OpenGL clip_from_view (NDC z in −1..1) for ``fov`` between the planes
    at distances ``near`` < ``far``: OpenXR's XrMatrix4x4f_CreateProjectionFov with
    GRAPHICS_OPENGL (row-major here, column-major there)."""
    if not 0 < near < far:
        raise ValueError(f"need 0 < near < far, got near={near}, far={far}")
    tan_left, tan_right = math.tan(fov.angle_left), math.tan(fov.angle_right)
    tan_down, tan_up = math.tan(fov.angle_down), math.tan(fov.angle_up)
    width, height = tan_right - tan_left, tan_up - tan_down
    return np.array(
        [
            [2 / width, 0.0, (tan_right + tan_left) / width, 0.0],
            [0.0, 2 / height, (tan_up + tan_down) / height, 0.0],
            [0.0, 0.0, -(far + near) / (far - near), -2 * far * near / (far - near)],
            [0.0, 0.0, -1.0, 0.0],
        ],
        dtype=np.float64,
    )


def eye_view_matrices(world_from_head: np.ndarray, ipd_m: float) -> dict[str, np.ndarray]:
    """{"left": view_from_world, "right": view_from_world}, (4, 4) float64 each: the eyes sit
    at ∓``ipd_m``/2 along the head's +x and look down its −z. ``world_from_head``: (4, 4),
    the head's pose (any invertible affine map, e.g. with a navigation scale)."""
    m = np.asarray(world_from_head, dtype=np.float64)
    if m.shape != (4, 4):
        raise ValueError(f"world_from_head must be (4, 4), got {m.shape}")
    if ipd_m < 0:
        raise ValueError(f"IPD must be >= 0, got {ipd_m}")
    views = {}
    for name, side in (("left", -1.0), ("right", 1.0)):
        head_from_eye = np.eye(4)
        head_from_eye[0, 3] = side * ipd_m / 2
        views[name] = np.linalg.inv(m @ head_from_eye)
    return views


@dataclass(frozen=True, eq=False)
class Eye:
    """One eye of a stereo frame: ``view_from_world`` and ``clip_from_view`` (4, 4) float64,
    its image ``width`` × ``height`` pixels."""

    name: str
    view_from_world: np.ndarray
    clip_from_view: np.ndarray
    width: int
    height: int

    @property
    def clip_from_world(self) -> np.ndarray:
        """(4, 4) float64: what the drawer's ``restart`` takes."""
        return self.clip_from_view @ self.view_from_world

    @property
    def position(self) -> np.ndarray:
        """(3,) float64: the eye's position in world space."""
        return np.linalg.inv(self.view_from_world)[:3, 3]


def stereo_eyes(
    profile: HeadsetProfile, world_from_head: np.ndarray, near: float = 0.1, far: float = 100.0
) -> list[Eye]:
    """[left, right] eyes of ``profile`` for a head at ``world_from_head`` ((4, 4))."""
    views = eye_view_matrices(world_from_head, profile.ipd_m)
    fovs = {"left": profile.fov_left_eye, "right": profile.fov_right_eye}
    return [
        Eye(
            name,
            views[name],
            projection_from_fov(fovs[name], near, far),
            profile.eye_width,
            profile.eye_height,
        )
        for name in ("left", "right")
    ]

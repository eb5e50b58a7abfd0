"""The data of the bridge's frame loop: the swapchain formats it writes, an eye's swapchain, a
view as the runtime located it, one frame's summary; and the conversions to and from
pyopenxr's pose/FOV structs."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..render.headsets import EyeFov

GL_SRGB8_ALPHA8 = 0x8C43
GL_RGBA16F = 0x881A
GL_RGBA8 = 0x8058
GL_FRAMEBUFFER_SRGB = 0x8DB9
#: Swapchain formats the bridge writes, best first, with (moderngl dtype, sRGB-encoded).
#: SRGB8_ALPHA8: our linear output encoded by the hardware (GL_FRAMEBUFFER_SRGB on);
#: RGBA16F and RGBA8 (UNORM): the runtime reads them as linear values, written as they are
#: (RGBA8 then bands in the darks: the last choice).
FORMATS: dict[int, tuple[str, bool, str]] = {
    GL_SRGB8_ALPHA8: ("f1", True, "GL_SRGB8_ALPHA8"),
    GL_RGBA16F: ("f2", False, "GL_RGBA16F"),
    GL_RGBA8: ("f1", False, "GL_RGBA8"),
}


@dataclass
class EyeSwapchain:
    """One eye's swapchain: ``handle``; ``width`` × ``height`` pixels; ``images``: the GL
    texture names; ``textures``, ``framebuffers``: moderngl wrappers of them, one per image;
    ``acquired``/``waited``: where the image protocol stands (what a teardown must end)."""

    handle: object
    width: int
    height: int
    images: list[int]
    textures: list = field(default_factory=list)
    framebuffers: list = field(default_factory=list)
    acquired: bool = False  # an image acquired and not yet released
    waited: bool = False  # ... and waited (xrWaitSwapchainImage)


@dataclass(frozen=True)
class LocatedView:
    """One eye as the runtime located it for a frame, in the reference space: ``position``
    (3,) metres, ``orientation`` (4,) quaternion (x, y, z, w), ``fov`` radians."""

    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]
    fov: EyeFov

    def space_from_eye(self) -> np.ndarray:
        """(4, 4) float64: the eye's pose as a matrix (OpenXR view space: +x right, +y up,
        looking down −z)."""
        x, y, z, w = self.orientation
        n = np.sqrt(x * x + y * y + z * z + w * w) or 1.0
        x, y, z, w = x / n, y / n, z / n, w / n
        m = np.eye(4)
        m[:3, :3] = [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
        m[:3, 3] = self.position
        return m


@dataclass(frozen=True)
class FrameInfo:
    """What one pass of the frame loop did: ``display_time`` (ns, the runtime's predicted
    time), ``period_s``; ``views``: the located views (empty when nothing was rendered);
    ``submitted``: whether a projection layer went to xrEndFrame."""

    display_time: int
    period_s: float
    views: tuple[LocatedView, ...]
    submitted: bool


def located_view(view) -> LocatedView:
    p, q, f = view.pose.position, view.pose.orientation, view.fov
    return LocatedView(
        (float(p.x), float(p.y), float(p.z)),
        (float(q.x), float(q.y), float(q.z), float(q.w)),
        EyeFov(float(f.angle_left), float(f.angle_right), float(f.angle_up), float(f.angle_down)),
    )


def set_pose(pv, view: LocatedView) -> None:
    p, q, f = pv.pose.position, pv.pose.orientation, pv.fov
    p.x, p.y, p.z = view.position
    q.x, q.y, q.z, q.w = view.orientation
    fov = view.fov
    f.angle_left, f.angle_right = fov.angle_left, fov.angle_right
    f.angle_up, f.angle_down = fov.angle_up, fov.angle_down


def swapchain_size(
    recommended: tuple[int, int], maximum: tuple[int, int], scale: float
) -> tuple[int, int]:
    """An eye's swapchain size: the runtime's ``recommended`` size times ``scale``, one factor
    for both sides so the eye keeps the recommended aspect (the view's FOV is drawn into it),
    within the runtime's ``maximum`` (a side of 0: none stated, the recommended size is the
    most) and at least 1 pixel a side. Clamping each side alone turned Monado's 4:3
    recommendation into 16:9 at ``--scale 10``."""
    w, h = max(1, recommended[0]), max(1, recommended[1])
    most_w, most_h = maximum[0] or w, maximum[1] or h
    factor = min(scale, most_w / w, most_h / h)
    return max(1, min(round(w * factor), most_w)), max(1, min(round(h * factor), most_h))

"""Draws the VR HUD (render/hud.py: the text raster and the quad's corners) through the Device
protocol (gl/device.py), so the same code runs on moderngl (tests) and on Blender's ``gpu``
module (the XR draw callback, blender/vr/preview.py, once per eye with that eye's matrices).

The quad's 6 vertices are uploaded once, as a static uv attribute; the corners and the
projection are uniforms (HUD_SHADER in gl/interface.py), because the Device makes vertex
buffers per program and a per-frame vertex upload per eye would be wasted work. The image is
uploaded only when its pixels change (the status text changes a few times a second at most;
the callback runs at the headset's rate).
"""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np

from .device import DEFAULT_STATE, OVER, Device
from .interface import HUD_SHADER

# Two triangles (bottom-left, bottom-right, top-left) and (top-left, bottom-right, top-right),
# as the uv of each corner: the vertex shader maps uv → corner.
_CORNER_UV = np.array(
    [[0, 0], [1, 0], [0, 1], [0, 1], [1, 0], [1, 1]],
    dtype=np.float32,
)


class HudDrawer:
    """One HUD image on one device; ``draw`` it once per eye. ``uploads`` counts texture
    uploads (set_image with changed pixels)."""

    def __init__(self, device: Device):
        self.device = device
        self.program = device.program(HUD_SHADER)
        self.vertices = device.vertices(self.program, {"corner_uv": _CORNER_UV})
        self.texture: Any = None
        self.image_size: tuple[int, int] | None = None  # (w, h) of the current image
        self.uploads = 0
        self._digest: bytes | None = None
        self._source: np.ndarray | None = None  # the array last given (see set_image)

    def set_image(self, image: np.ndarray) -> None:
        """``image``: ``(h, w, 4)`` float32, premultiplied alpha, row 0 at the bottom (as
        render/hud.py ``raster_text`` makes it). Uploaded only if its pixels (or shape)
        differ from the current image's; the very array of the last call (an eye draws its
        HUD image again every frame until the text changes) is not even hashed: images are
        made anew, never changed in place (render/hud.py)."""
        if image is self._source:
            return
        source = image
        image = np.ascontiguousarray(image, dtype=np.float32)
        if image.ndim != 3 or image.shape[2] != 4 or image.shape[0] < 1 or image.shape[1] < 1:
            raise ValueError(f"HUD image must be (h, w, 4), got {image.shape}")
        digest = hashlib.blake2b(image.tobytes(), digest_size=16)
        digest.update(repr(image.shape).encode())
        if digest.digest() == self._digest:
            self._source = source
            return
        # linear: the quad is rarely pixel-aligned with the eye's image; premultiplied texels
        # filter without dark fringes. Blender's adapter keeps its default sampler (it may
        # repeat at the edges): raster_text's border is background padding on every side, so
        # clamping and repeating filter the same values there.
        texture = self.device.texture(image, linear=True)
        self.device.release(self.texture)
        self.texture, self._digest, self._source = texture, digest.digest(), source
        self.image_size = (image.shape[1], image.shape[0])
        self.uploads += 1

    def draw(self, clip_from_view: np.ndarray, corners: np.ndarray) -> None:
        """Draw the image on the quad into the BOUND target: premultiplied "over" blending, no
        depth test, then DEFAULT_STATE again. ``clip_from_view``: ``(4, 4)`` this eye's
        projection (row-major numpy); ``corners``: ``(4, 3)`` view-space bottom-left,
        bottom-right, top-left, top-right (render/hud.py ``hud_quad``)."""
        if self.texture is None:
            raise RuntimeError("HudDrawer.draw before set_image: there is no HUD image yet")
        clip_from_view = np.asarray(clip_from_view, dtype=np.float32)
        corners = np.asarray(corners, dtype=np.float64)
        if clip_from_view.shape != (4, 4) or corners.shape != (4, 3):
            raise ValueError(
                f"need a (4, 4) projection and (4, 3) corners, got {clip_from_view.shape} "
                f"and {corners.shape}"
            )
        view_corners = np.ones((4, 4), dtype=np.float32)
        view_corners[:3, :] = corners.T  # column i = corner i (GLSL's view_corners[i])
        try:
            self.device.set_state(OVER)
            self.device.draw(
                self.program,
                self.vertices,
                {"clip_from_view": clip_from_view, "view_corners": view_corners},
                {"hud_image": self.texture},
            )
        finally:
            self.device.set_state(DEFAULT_STATE)

    def release(self) -> None:
        """Free the texture and the vertex buffer (the program stays in the device's cache)."""
        self.device.release(self.texture, self.vertices)
        self.texture = self.vertices = None
        self._digest = None

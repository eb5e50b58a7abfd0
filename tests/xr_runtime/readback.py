"""Reads what the test runtime captured at each xrEndFrame (see docs/development.md,
"The OpenXR test runtime"): ``frame_%05d.json`` plus one raw float32 RGBA file per view."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """The sRGB EOTF (IEC 61966-2-1), as GL applies it when sampling an sRGB texture."""
    v = np.asarray(v, dtype=np.float32)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4).astype(np.float32)


@dataclass
class View:
    image: np.ndarray  # (h, w, 4) float32, LINEAR, row 0 at the bottom (GL order)
    pose: tuple  # as submitted: (x, y, z, qx, qy, qz, qw) in the layer's space
    fov: tuple  # as submitted: (angleLeft, angleRight, angleUp, angleDown), radians
    format: int  # the swapchain's GLenum
    rect: tuple  # (x, y, w, h) of the sub-image in its swapchain
    width: int  # swapchain image size
    height: int
    encoding: str  # what the file held: "srgb" (decoded here) or "linear"
    located_pose: tuple  # what xrLocateViews reports for this display time and space
    located_fov: tuple
    readback_ok: bool = True  # False: glGetTexImage failed (the image is zeros; see stderr)


@dataclass
class Frame:
    frame: int  # 0-based count of xrEndFrame calls before this one
    display_time: int  # XrTime (ns) the app submitted
    space: str  # the projection layer's reference space: VIEW, LOCAL or STAGE
    head: tuple = ()  # the script's head pose at display_time (LOCAL = STAGE = world space)
    views: list[View] = field(default_factory=list)


def read_capture(directory: Path) -> list[Frame]:
    """Every captured frame in ``directory``, in submission order."""
    frames = []
    for path in sorted(Path(directory).glob("frame_?????.json")):
        meta = json.loads(path.read_text())
        frame = Frame(
            meta["frame"], meta["display_time"], meta.get("space", ""), tuple(meta.get("head", ()))
        )
        for v in meta["views"]:
            w, h = v["rect"][2], v["rect"][3]
            raw = np.fromfile(path.parent / v["file"], dtype=np.float32)
            image = raw.reshape(h, w, 4)
            if v.get("encoding") == "srgb":  # alpha is never encoded
                image = np.concatenate([srgb_to_linear(image[..., :3]), image[..., 3:]], axis=-1)
            frame.views.append(
                View(
                    image=image,
                    pose=tuple(v["pose"]),
                    fov=tuple(v["fov"]),
                    format=v["format"],
                    rect=tuple(v["rect"]),
                    width=v["width"],
                    height=v["height"],
                    encoding=v.get("encoding", "linear"),
                    located_pose=tuple(v.get("located_pose", ())),
                    located_fov=tuple(v.get("located_fov", ())),
                    readback_ok=v.get("readback_ok", True),
                )
            )
        frames.append(frame)
    return frames

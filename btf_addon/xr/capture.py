"""Captures of what the bridge submitted: per frame and eye, the linear image drawn (EXR) and a
JSON beside it with everything needed to draw it again independently.

Files in the capture directory, for frame ``n`` (the bridge's submitted-frame index from 0)
and eye ``e`` (``left``/``right``):

- ``frame_{n:05d}_{e}.exr``: float32 RGB, scene-linear, exposure applied, HUD included when
  it was drawn; row 0 at the TOP (image order);
- ``frame_{n:05d}_{e}.json``: ``frame``, ``eye``, ``display_time_ns``, ``runtime``,
  ``pose`` ([x, y, z, qx, qy, qz, qw] in the reference space, as submitted), ``fov``
  ([left, right, up, down] radians, as submitted), ``reference_space``,
  ``world_from_space`` (4×4, row-major: the reference space placed in the scene),
  ``view_from_world`` and ``clip_from_view`` (4×4 the image was drawn with), ``near``/``far``,
  ``lights_done``/``lights_total`` (accumulated in this image), ``lights_this_frame``,
  ``exposure`` (stops), ``eye_size`` ([w, h]), ``format`` (the swapchain's GL enum),
  ``values_from``, ``image`` (the EXR's file name).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..core.fileio import atomic_write
from ..core.formats.imageio import write_exr
from ..core.interrupts import deferred


def write_frame(directory: Path, frame: int, eyes: list[tuple[str, np.ndarray, dict]]) -> None:
    """Both eyes of one frame, whole or not at all: ``eyes`` holds per eye its name, the image
    ((h, w, 4) float32 linear RGBA, row 0 at the BOTTOM, OpenGL's readback) and ``meta`` (the
    JSON gets ``frame``, ``eye`` and ``image`` too). Every file is first written under a
    staging name, then all are renamed; an error anywhere removes what this frame had
    written, so a check never finds a left eye without its right, or an EXR without its JSON.
    Ctrl-C and SIGTERM are held back while the frame is written (core/interrupts.py; one
    frame's files, then the interrupt lands): one landing in the cleanup itself, or between a
    rename and its record, would leave part of a frame (tests/xr/test_bridge_interrupts.py
    found both)."""
    with deferred():
        _write_frame(directory, frame, eyes)


def _write_frame(directory: Path, frame: int, eyes: list[tuple[str, np.ndarray, dict]]) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    staged: list[tuple[Path, Path]] = []
    placed: list[Path] = []
    try:
        for eye, image, meta in eyes:
            stem = f"frame_{frame:05d}_{eye}"
            exr, js = directory / f"{stem}.exr", directory / f"{stem}.json"
            record = {"frame": frame, "eye": eye, **meta, "image": exr.name}
            text = json.dumps(_plain(record), indent=1).encode()
            staged.append((directory / f".{stem}.staged.exr", exr))
            write_exr(staged[-1][0], np.ascontiguousarray(image[::-1, :, :3]))
            staged.append((directory / f".{stem}.staged.json", js))
            atomic_write(staged[-1][0], lambda f, text=text: f.write(text))
        for tmp, final in staged:
            os.replace(tmp, final)
            placed.append(final)
    except BaseException:
        for path in [*(tmp for tmp, _ in staged), *placed]:
            path.unlink(missing_ok=True)
        raise


def _plain(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value

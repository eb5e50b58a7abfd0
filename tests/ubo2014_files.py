"""UBO2014 DFMF files written field by field from btflib's layout (not our writer): the
reader's tests and the CLI's raw-units test build their files here."""

from __future__ import annotations

import struct

import numpy as np

YUV_TO_RGB = np.array([[1.0, 0.0, 1.13983], [1.0, -0.39465, -0.5806], [1.0, 2.03211, 0.0]])


def _text(s: bytes) -> bytes:
    return s + b"\0" * (80 - len(s))


def hand_built(version: int = 4, scalar: int = 4, colour_model: int = 1) -> tuple[bytes, dict]:
    """A 2×1-texel DFMF file written field by field from btflib's layout (not our writer).

    Views: the pole (θ 0) and θ 45° at φ 180° then 0° (file order not ring order, so the reader
    must reorder); lights: the pole and θ 30° at φ 0°, 120°, 240°. Rank 2 in Y, 1 in U and V."""
    views = [(0.0, 0.0), (np.pi / 4, np.pi), (np.pi / 4, 0.0)]
    lights = [(0.0, 0.0), (np.pi / 6, 0.0), (np.pi / 6, 2 * np.pi / 3), (np.pi / 6, 4 * np.pi / 3)]
    meta = struct.pack("<I", version) + _text(b"setup") + _text(b"sensor") + _text(b"led")
    meta += struct.pack("<f3f", 40.0, 1.0, 0.5, 2.0)  # ppmm, RGB scale
    if version > 1:
        meta += struct.pack("<I", 1)  # cosine in data
    if version > 2:
        meta += struct.pack("<I", 5) + b"<x/>\0"
    if version > 3:
        meta += struct.pack("<I", 3) + b"".join(
            struct.pack("<I", 1) + c for c in (b"Y", b"U", b"V")
        )
    blob = b"!DFMF08FCR" + struct.pack("<I", len(meta) + 4) + meta
    blob += struct.pack("<I", len(views))
    for t, p in views:
        blob += struct.pack("<ffI", t, p, len(lights))
        blob += b"".join(struct.pack("<ff", lt, lp) for lt, lp in lights)
    blob += struct.pack("<II", 2, 1)  # width 2, height 1
    blob += struct.pack("<I", 1) + struct.pack("<9f", *np.eye(3).ravel())  # one rotation
    blob += struct.pack("<Ii", 2, colour_model) + struct.pack("<3f", 0, 0, 0)
    blob += struct.pack("<9f", *np.eye(3).ravel())
    rows = len(views) * len(lights)
    rng = np.random.default_rng(7)
    u = [rng.random((rows, k)).astype(np.float32) for k in (2, 1, 1)]
    sv = [rng.random((2, k)).astype(np.float32) * s for k, s in ((2, 1.0), (1, 0.1), (1, 0.1))]
    fmt = "<f4" if scalar == 4 else "<f2"
    for c in range(3):
        k = u[c].shape[1]
        blob += struct.pack("<BIII", scalar, k, rows, 2)
        blob += np.ones(k, fmt).tobytes() + u[c].astype(fmt).tobytes()
        blob += sv[c].astype(fmt).tobytes()
    return blob, {"u": u, "sv": sv, "views": views, "lights": lights}

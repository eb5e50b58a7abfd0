"""Radiance ``.hdr`` (RGBE) images: a reader (flat and run-length-encoded scanlines) and a
flat writer, numpy only — OpenEXR reads neither this nor JPEG, and the format is small enough
to own (Ward, "Real Pixels", Graphics Gems II; Radiance's color.c for the decode).

Header: ``#?RADIANCE`` or ``#?RGBE``, ``KEY=value`` lines (``FORMAT=32-bit_rle_rgbe``; an
``EXPOSURE=e`` line means the stored values are the original × e, so they are divided by it),
an empty line, then the resolution line ``-Y H +X W`` (rows from the top, columns left to
right; other orientations are refused). Pixels are (R, G, B, E) bytes: value =
(m + 0.5)·2^(E − 136), and 0 when E = 0. A scanline of width 8…32767 starting 2, 2 is
run-length encoded per channel (count > 128: a run of count − 128 copies of the next byte;
else count literal bytes).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import BTFFormatError

MAX_SIDE = 1 << 15


def _header(data: bytes, name: str) -> tuple[int, int, float, int]:
    """(height, width, exposure, offset of the first scanline)."""
    if not (data.startswith(b"#?RADIANCE") or data.startswith(b"#?RGBE")):
        raise BTFFormatError(f"{name}: not a Radiance .hdr file (no #?RADIANCE header)")
    pos, exposure = 0, 1.0
    while True:
        end = data.find(b"\n", pos)
        if end < 0 or end - pos > 4096:
            raise BTFFormatError(f"{name}: truncated .hdr header")
        line = data[pos:end].strip()
        pos = end + 1
        if not line:
            break
        if line.startswith(b"FORMAT=") and line != b"FORMAT=32-bit_rle_rgbe":
            raise BTFFormatError(f"{name}: unsupported .hdr pixel format {line[7:]!r}")
        if line.startswith(b"EXPOSURE="):
            try:
                exposure *= float(line[9:])
            except ValueError:
                raise BTFFormatError(f"{name}: bad EXPOSURE line {line!r}") from None
    end = data.find(b"\n", pos)
    fields = data[pos:end].split() if end > 0 else []
    if len(fields) != 4 or fields[0] != b"-Y" or fields[2] != b"+X":
        raise BTFFormatError(f"{name}: resolution line must be '-Y H +X W', found {fields!r}")
    try:
        height, width = int(fields[1]), int(fields[3])
    except ValueError:
        raise BTFFormatError(f"{name}: bad resolution line") from None
    if not (0 < height <= MAX_SIDE and 0 < width <= MAX_SIDE) or not exposure > 0:
        raise BTFFormatError(f"{name}: size {width}×{height} or exposure {exposure} invalid")
    return height, width, exposure, end + 1


def _rle_scanline(data: bytes, pos: int, width: int, name: str) -> tuple[np.ndarray, int]:
    out = np.empty((4, width), dtype=np.uint8)
    for c in range(4):
        x = 0
        while x < width:
            if pos >= len(data):
                raise BTFFormatError(f"{name}: truncated run-length data")
            count = data[pos]
            if count > 128:
                count -= 128
                if x + count > width or pos + 1 >= len(data):
                    raise BTFFormatError(f"{name}: run-length data overruns its scanline")
                out[c, x : x + count] = data[pos + 1]
                pos += 2
            else:
                if count == 0 or x + count > width or pos + 1 + count > len(data):
                    raise BTFFormatError(f"{name}: run-length data overruns its scanline")
                out[c, x : x + count] = np.frombuffer(data, np.uint8, count, pos + 1)
                pos += 1 + count
            x += count
    return out.T, pos


def decode_hdr(data: bytes, name: str = "<hdr>") -> np.ndarray:
    """.hdr bytes → (H, W, 3) float32, row 0 the top of the image."""
    height, width, exposure, pos = _header(data, name)
    rgbe = np.empty((height, width, 4), dtype=np.uint8)
    for y in range(height):
        head = data[pos : pos + 4]
        if 8 <= width < 32768 and len(head) == 4 and head[0] == 2 and head[1] == 2:
            if (head[2] << 8 | head[3]) != width:
                raise BTFFormatError(f"{name}: scanline {y} declares a different width")
            rgbe[y], pos = _rle_scanline(data, pos + 4, width, name)
        else:
            if pos + 4 * width > len(data):
                raise BTFFormatError(f"{name}: truncated at scanline {y} of {height}")
            rgbe[y] = np.frombuffer(data, np.uint8, 4 * width, pos).reshape(width, 4)
            pos += 4 * width
    e = rgbe[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0)
    rgb = (rgbe[..., :3].astype(np.float64) + 0.5) * scale[..., None]
    return (rgb / exposure).astype(np.float32)


def read_hdr(path: str | Path) -> np.ndarray:
    path = Path(path)
    try:
        return decode_hdr(path.read_bytes(), str(path))
    except OSError as exc:
        raise BTFFormatError(f"{path}: cannot read ({exc.strerror})") from None


def encode_hdr(rgb: np.ndarray) -> bytes:
    """(H, W, 3) non-negative floats → flat (not run-length encoded) .hdr bytes. Each value is
    kept to 8 bits of mantissa relative to the pixel's largest channel."""
    rgb = np.maximum(np.nan_to_num(np.asarray(rgb, dtype=np.float64)), 0.0)
    h, w, _ = rgb.shape
    peak = rgb.max(axis=2)
    mant, exp = np.frexp(peak)
    ok = peak > 1e-32
    scale = np.where(ok, mant * 256.0 / np.where(ok, peak, 1.0), 0.0)
    rgbe = np.zeros((h, w, 4), dtype=np.uint8)
    rgbe[..., :3] = np.clip(np.floor(rgb * scale[..., None]), 0, 255)
    rgbe[..., 3] = np.where(ok, np.clip(exp + 128, 0, 255), 0)
    head = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode()
    return head + rgbe.tobytes()

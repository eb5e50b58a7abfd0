"""Image files: OpenEXR (float, through the OpenEXR package) and 8-bit PNG (stdlib zlib).

Arrays are (height, width, channels) with row 0 at the **top** of the image, as files store
them. OpenEXR is imported inside the functions: the rest of the core stays numpy-only. Writes
are atomic (core/fileio.py), so a failed or interrupted write
never leaves a half-written image under the requested name.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from ..colour import srgb_encode
from ..errors import BTFFormatError
from ..fileio import atomic_write, atomic_write_path


def write_exr(path: str | Path, rgb: np.ndarray) -> Path:
    """(H, W, 3) float → 32-bit float RGB EXR, ZIP compressed."""
    import OpenEXR

    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    return atomic_write_path(path, lambda p: OpenEXR.File(header, {"RGB": rgb}).write(str(p)))


def read_exr(path: str | Path) -> np.ndarray:
    """An EXR's colour channels → (H, W, 3) float32 (grey images are repeated to RGB)."""
    try:
        import OpenEXR
    except ImportError:
        raise BTFFormatError(
            "reading EXR needs the OpenEXR package (pip install openexr)"
        ) from None
    path = Path(path)
    if not path.is_file():
        raise BTFFormatError(f"{path}: no such file")
    try:
        with OpenEXR.File(str(path)) as exr:
            channels = {name: np.asarray(ch.pixels) for name, ch in exr.channels().items()}
    except Exception as exc:  # the binding raises plain exceptions for corrupt files
        raise BTFFormatError(f"{path}: not a readable OpenEXR file ({exc})") from None
    if "RGB" in channels or "RGBA" in channels:
        rgb = channels.get("RGB", channels.get("RGBA"))[..., :3]
    elif all(c in channels for c in "RGB"):
        rgb = np.stack([channels[c] for c in "RGB"], axis=-1)
    elif "Y" in channels:
        rgb = np.repeat(channels["Y"][..., None], 3, axis=-1)
    else:
        raise BTFFormatError(f"{path}: no R, G, B or Y channels (found {sorted(channels)})")
    return np.asarray(rgb, dtype=np.float32)


def exr_size(path: str | Path) -> tuple[int, int]:
    """(width, height) of an EXR from its header alone (no pixels read): what the memory model
    needs before a large map is loaded."""
    try:
        import OpenEXR
    except ImportError:
        raise BTFFormatError(
            "reading EXR needs the OpenEXR package (pip install openexr)"
        ) from None
    path = Path(path)
    if not path.is_file():
        raise BTFFormatError(f"{path}: no such file")
    try:
        with OpenEXR.File(str(path), header_only=True) as exr:
            (x0, y0), (x1, y1) = (np.asarray(c).tolist() for c in exr.header()["dataWindow"])
    except Exception as exc:  # the binding raises plain exceptions for corrupt files
        raise BTFFormatError(f"{path}: not a readable OpenEXR file ({exc})") from None
    width, height = int(x1) - int(x0) + 1, int(y1) - int(y0) + 1
    if width < 1 or height < 1:
        raise BTFFormatError(f"{path}: empty data window ({width}×{height})")
    return width, height


def write_png(path: str | Path, rgb8: np.ndarray) -> Path:
    """(H, W, 3) uint8 → PNG (filter 0 per row, zlib level 6)."""
    rgb8 = np.ascontiguousarray(rgb8, dtype=np.uint8)
    h, w = rgb8.shape[:2]
    raw = b"".join(b"\0" + rgb8[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data))
            + kind
            + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        )

    png = (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw, 6))
        + chunk(b"IEND", b"")
    )
    return atomic_write(path, lambda fh: fh.write(png))


def srgb8_from_linear(rgb: np.ndarray) -> np.ndarray:
    """Linear display values (1.0 = white) → 8-bit sRGB with clipping; NaN → 0."""
    c = np.clip(np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0), 0.0, 1.0)
    return np.round(srgb_encode(c) * 255.0).astype(np.uint8)

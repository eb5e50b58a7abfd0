"""Writer for UBO2014 DFMF ``.btf`` files (the layout in core/formats/ubo2014.py and
docs/formats.md).

Writes meta version 4 (cosine flag, empty XML, three channel names), the direction sampling of
the svd BTF's ring grids in ring order (angles in radians), no rotations, and each channel's
factors as half (scalar size 2, btflib's default) or float (4) scalars. S is written as the
norms of the S·V columns (btflib stores S beside S·V; decoding uses only U and S·V).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from ..codecs.svd import SVDBTF
from ..errors import BTFError
from ..fileio import atomic_write
from .ubo2014 import SIGNATURE

_CHANNEL_NAMES = {
    0: ("R", "G", "B"),
    1: ("Y", "U", "V"),
    3: ("P0", "P1", "P2"),
    4: ("Y", "Co", "Cg"),
    9: ("logY", "U", "V"),
    12: ("logR", "logG", "logB"),
}


def _text80(text: str) -> bytes:
    raw = text.encode("utf-8")[:79]
    return raw + b"\0" * (80 - len(raw))


def meta_block(btf: SVDBTF, ppmm: float) -> bytes:
    """The meta block, version 4, its size field included."""
    p = btf.p
    names = _CHANNEL_NAMES.get(p.colour_model, ("C0", "C1", "C2"))
    body = struct.pack("<I", 4)
    body += _text80("btf_materials svd export") + _text80("") + _text80("")
    body += struct.pack("<f3f", ppmm, *p.rgb_scale)
    body += struct.pack("<I", int(p.cosine_in_data))
    body += struct.pack("<I", 0)  # XML length
    body += struct.pack("<I", 3)
    for name in names:
        body += struct.pack("<I", len(name)) + name.encode()
    return struct.pack("<I", len(body) + 4) + body


def dfmf_bytes(btf: SVDBTF, scalar_size: int = 2) -> bytes:
    """The whole file as bytes (tests build files this way; ``write_ubo2014`` writes them)."""
    if scalar_size not in (2, 4):
        raise BTFError(f"scalar size {scalar_size}: write 2 (half) or 4 (float)")
    p = btf.p
    dtype = "<f2" if scalar_size == 2 else "<f4"
    ppmm = p.width / p.tile_size_mm[0] if p.tile_size_mm[0] > 0 else 0.0
    out = [SIGNATURE, meta_block(btf, ppmm)]
    vt, vp = p.view_grid.angles_deg()[0], p.phis("view")
    lt, lp = p.light_grid.angles_deg()[0], p.phis("light")
    lights = np.column_stack([np.radians(lt), np.radians(lp)]).astype("<f4")
    out.append(struct.pack("<I", len(vt)))
    for t, ph in zip(vt, vp, strict=True):
        out.append(struct.pack("<ffI", np.radians(t), np.radians(ph), len(lt)))
        out.append(lights.tobytes())
    out.append(struct.pack("<III", p.width, p.height, 0))  # no rotations
    ranks = btf.ranks
    out.append(struct.pack("<Ii", max(ranks), p.colour_model))
    out.append(np.asarray(p.colour_mean, "<f4").tobytes())
    out.append(np.asarray(p.pca_matrix, "<f4").tobytes())
    for c in range(3):
        u = btf.u[c]
        # Ours: texel row 0 is v = 0 (the bottom); the file's rows start at the image's top.
        sv = btf.sv[c].reshape(p.height, p.width, -1)[::-1].reshape(p.width * p.height, -1)
        if scalar_size == 2 and max(np.abs(u).max(), np.abs(sv).max()) > 65504:
            raise BTFError(f"channel {c}: factors exceed the half-float range; write floats")
        out.append(struct.pack("<BIII", scalar_size, u.shape[1], u.shape[0], sv.shape[0]))
        out.append(np.linalg.norm(sv, axis=0).astype(dtype).tobytes())
        out.append(u.astype(dtype).tobytes())
        out.append(sv.astype(dtype).tobytes())
    return b"".join(out)


def write_ubo2014(path: str | Path, btf: SVDBTF, scalar_size: int = 2) -> None:
    """An svd BTF → a DFMF ``.btf`` file, written atomically."""
    if btf.meta.codec != "svd":
        raise BTFError(
            f"{btf.meta.name}: only svd BTFs are written as UBO2014 .btf (this is "
            f"{btf.meta.codec!r})"
        )
    data = dfmf_bytes(btf, scalar_size)
    atomic_write(Path(path), lambda fh: fh.write(data))

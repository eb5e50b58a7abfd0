"""Will a BTF's packed tables fit the GPU? If not, a reduced-resolution copy that does.

The packed float stream (core/codecs/packed.py) becomes one R32F texture TABLE_WIDTH texels wide,
and
the GLSL back end addresses it with offsets stored exactly as float32 integers. So a BTF fits
when its stream has fewer than 2^24 floats (exact offsets), at most ``max_texture_size`` rows
and at most ``max_bytes`` bytes. Large tabulated BTFs — an svd BTF at 400² and high rank, a
dense one at 256² on the UBO grid — can exceed that; their spatial resolution is then halved
(box filter: ``svd_build.reduce_resolution``, the same for dense data) until they fit, with a
message saying so, instead of a failed draw.
"""

from __future__ import annotations

import numpy as np

from ..errors import UnsupportedBTFError
from ..model import BTF, box_reduce, innermost
from .dense import DenseBTF
from .packed import MAX_EXACT_INT, TABLE_WIDTH
from .svd import SVDBTF
from .svd_build import reduce_resolution

#: Defaults when the device does not report its own: the common desktop texture limit and a
#: quarter of an 8 GB card.
MAX_TEXTURE_SIZE = 16384
MAX_BYTES = 2 << 30


def packed_floats(btf: BTF) -> int | None:
    """Floats in the packed stream of the big codecs (None: small or unknown, not estimated)."""
    if isinstance(btf, SVDBTF):
        return sum(u.size + sv.size for u, sv in zip(btf.u, btf.sv, strict=True)) + 1024
    if isinstance(btf, DenseBTF):
        return btf.data.size + 1024
    return None


def _reduce_dense(btf: DenseBTF, factor: int) -> DenseBTF:
    # Texel axes first for box_reduce, then back: (nv, nl, h, w, 3).
    data = box_reduce(np.moveaxis(btf.data, (2, 3), (0, 1)), factor, btf.meta.name)
    data = np.moveaxis(data, (0, 1), (2, 3))
    return DenseBTF(
        data, btf.view_grid, btf.light_grid, f"{btf.meta.name} (1/{factor})", btf.meta.tile_size_mm
    )


def fits(n_floats: int, max_texture_size: int, max_bytes: int) -> bool:
    rows = -(-n_floats // TABLE_WIDTH)
    return n_floats < MAX_EXACT_INT and rows <= max_texture_size and 4 * n_floats <= max_bytes


def fit_for_gpu(
    btf: BTF,
    max_texture_size: int = MAX_TEXTURE_SIZE,
    max_bytes: int = MAX_BYTES,
    who: str = "the viewport draws",
) -> tuple[BTF, str | None]:
    """(the BTF to upload, a message when it had to be reduced). Raises UnsupportedBTFError
    with the sizes when even a 1×1-texel copy would not fit. ``who``: what the message says
    uses the copy ("the final render traces" for OpenCL, whose buffers hold the same layout:
    offsets as float32, so the 2^24 limit is the same)."""
    btf = innermost(btf)
    n = packed_floats(btf)
    if n is None or fits(n, max_texture_size, max_bytes):
        return btf, None
    reduce = reduce_resolution if isinstance(btf, SVDBTF) else _reduce_dense
    factor = 2
    while factor <= min(btf.meta.width, btf.meta.height):
        smaller = reduce(btf, factor)
        m = packed_floats(smaller)
        assert m is not None
        if fits(m, max_texture_size, max_bytes):
            return smaller, (
                f"{btf.meta.name}: {n * 4 / 2**20:.0f} MiB of tables exceed the GPU's limits "
                f"(texture height {max_texture_size} × {TABLE_WIDTH}, {max_bytes / 2**20:.0f} "
                f"MiB, offsets below 2^24); {who} it at {smaller.meta.width}×"
                f"{smaller.meta.height} texels instead of {btf.meta.width}×{btf.meta.height} "
                "(box-filtered)"
            )
        factor *= 2
    raise UnsupportedBTFError(
        f"{btf.meta.name}: its angular tables alone ({n * 4 / 2**20:.0f} MiB at full size) do not "
        "fit the GPU's texture limits even at 1×1 texels"
    )

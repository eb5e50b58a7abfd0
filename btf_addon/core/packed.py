"""Pack a BTF's tables into two 2D textures for GLSL (layout read by shaders/btf_tables_lib.glsl).

Every table is flattened and appended to an integer or a float stream; each stream is laid out
row by row TABLE_WIDTH texels wide (wide tables such as wallpaper's 31,291 × 11 PDF2 scales
would exceed the 16,384-texel height limit as 2D textures of their own). The first texels hold a
header — sizes and each table's offset — so shaders need no push constants for the layout and
any number of tables costs two samplers (the limit is 16 on Metal).

Both streams are float32 textures (R32F): Blender's ``gpu`` module only uploads float data, and
integers are exact in float32 up to 2^24, which ``pack`` checks. (Reinterpreting int bits as
floats would be exact too, but small integers become denormals that some GPUs flush to zero.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .analytic import GGXBTF, LambertianBTF, PrincipledBTF
from .dense import DenseBTF
from .errors import UnsupportedBTFError
from .mlvq import MLVQBTF
from .model import BTF

TABLE_WIDTH = 4096
HEADER_INTS = 40
HEADER_FLOATS = 12
CODEC_IDS = {"mlvq": 1, "lambertian": 2, "ggx": 3, "dense": 4, "principled": 5}
MAGIC = 0xB7F1  # header check value, exact in float32
MAX_EXACT_INT = 1 << 24

# Integer header slots; shaders/btf_tables_lib.glsl names the same numbers (H_*).
INT_HEADER = [
    "magic",
    "codec",
    "n_beta",
    "n_alpha",
    "n_theta",
    "n_phi",
    "width",
    "height",
    "rows_offset",
    "cols_offset",
    "hdr",
    "cos_beta",
    "index_ab",
    "pdf2_colours",
    "pdf2_slices",
    "pdf2_indices",
    "pdf3_slices",
    "pdf4_slices",
    "pdf6_slices",
    "f_pdf1",
    "f_ab_colors",
    "f_pdf2_scale",
    "f_pdf3_scale",
    "f_pdf4_scale",
    "f_pdf6_scale",
    "f_beta",
    "n_lights",
    "f_data",
    "n_view_rings",
    "f_view_theta",
    "view_offsets",
    "n_light_rings",
    "f_light_theta",
    "light_offsets",
]
FLOAT_HEADER = [
    "value_scale",
    "hdr_value",
    "albedo_r",
    "albedo_g",
    "albedo_b",
    "alpha2",
    "metallic",
    "diffuse_roughness",
    "specular_f0",
]


@dataclass
class PackedTables:
    """ints: (rows, TABLE_WIDTH) float32 holding exact integers; floats: (rows, TABLE_WIDTH)
    float32."""

    ints: np.ndarray
    floats: np.ndarray


def _layout(stream: np.ndarray, dtype) -> np.ndarray:
    rows = max(1, -(-len(stream) // TABLE_WIDTH))
    out = np.zeros(rows * TABLE_WIDTH, dtype=dtype)
    out[: len(stream)] = stream
    return out.reshape(rows, TABLE_WIDTH)


def pack(btf: BTF) -> PackedTables:
    codec = btf.meta.codec
    if codec not in CODEC_IDS:
        raise UnsupportedBTFError(
            f"the GPU back ends (GLSL, OpenCL) do not evaluate {codec!r} BTFs; tabulate "
            "procedural presets first (synth --tabulate) or use the numpy back end"
        )
    ih = dict.fromkeys(INT_HEADER, 0)
    assert len(INT_HEADER) <= HEADER_INTS
    fh = dict.fromkeys(FLOAT_HEADER, 0.0)
    ih["magic"], ih["codec"] = MAGIC, CODEC_IDS[codec]
    fh["value_scale"] = btf.meta.value_scale
    ints: list[np.ndarray] = []
    floats: list[np.ndarray] = []
    int_cursor, float_cursor = HEADER_INTS, HEADER_FLOATS

    def add(table: np.ndarray, integer: bool) -> int:
        nonlocal int_cursor, float_cursor
        flat = np.ascontiguousarray(table).ravel()
        if integer:
            offset, int_cursor = int_cursor, int_cursor + flat.size
            ints.append(flat.astype(np.int32))
        else:
            offset, float_cursor = float_cursor, float_cursor + flat.size
            floats.append(flat.astype(np.float32))
        return offset

    if isinstance(btf, MLVQBTF):
        p, t = btf.p, btf.t
        height, width = t["pdf6_slices"].shape
        ih.update(
            n_beta=p.n_beta,
            n_alpha=p.n_alpha,
            n_theta=p.n_theta,
            n_phi=p.n_phi,
            width=width,
            height=height,
            rows_offset=p.rows_offset,
            cols_offset=p.cols_offset,
            hdr=int(p.hdr),
            cos_beta=int(p.use_cos_beta),
        )
        for name in (
            "index_ab",
            "pdf2_colours",
            "pdf2_slices",
            "pdf2_indices",
            "pdf3_slices",
            "pdf4_slices",
            "pdf6_slices",
        ):
            ih[name] = add(t[name], integer=True)
        for name in ("pdf1", "ab_colors", "pdf2_scale", "pdf3_scale", "pdf4_scale", "pdf6_scale"):
            ih["f_" + name] = add(t[name], integer=False)
        ih["f_beta"] = add(p.beta_angles_deg(), integer=False)
        fh["hdr_value"] = p.hdr_value
    elif isinstance(btf, DenseBTF):
        ih.update(width=btf.meta.width, height=btf.meta.height, n_lights=btf.light_grid.size)
        ih["f_data"] = add(btf.data, integer=False)
        for prefix, grid in (("view", btf.view_grid), ("light", btf.light_grid)):
            ih[f"n_{prefix}_rings"] = len(grid.counts)
            ih[f"f_{prefix}_theta"] = add(np.asarray(grid.theta_deg), integer=False)
            ih[f"{prefix}_offsets"] = add(
                np.concatenate([[0], np.cumsum(grid.counts)]), integer=True
            )
    elif isinstance(btf, LambertianBTF | GGXBTF):
        fh["albedo_r"], fh["albedo_g"], fh["albedo_b"] = btf.albedo
        if isinstance(btf, GGXBTF):
            fh["alpha2"] = btf.alpha2
    elif isinstance(btf, PrincipledBTF):
        fh["albedo_r"], fh["albedo_g"], fh["albedo_b"] = btf.base_color
        fh["alpha2"], fh["metallic"] = btf.alpha2, btf.metallic
        fh["diffuse_roughness"], fh["specular_f0"] = btf.diffuse_roughness, btf.specular_f0
    int_stream = np.concatenate(
        [
            np.array(
                [ih[k] for k in INT_HEADER] + [0] * (HEADER_INTS - len(INT_HEADER)), dtype=np.int32
            ),
            *ints,
        ]
    )
    float_stream = np.concatenate(
        [
            np.array(
                [fh[k] for k in FLOAT_HEADER] + [0.0] * (HEADER_FLOATS - len(FLOAT_HEADER)),
                dtype=np.float32,
            ),
            *floats,
        ]
    )
    if int_stream.size and (
        int_stream.max() >= MAX_EXACT_INT or int_stream.min() <= -MAX_EXACT_INT
    ):
        raise UnsupportedBTFError(
            f"{btf.meta.name}: index tables too large for the GLSL back end (an index or offset "
            "reaches 2^24); use the OpenCL or numpy back end"
        )
    return PackedTables(_layout(int_stream, np.float32), _layout(float_stream, np.float32))

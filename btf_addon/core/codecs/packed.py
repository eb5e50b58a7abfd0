"""The packed GPU table layout: the one definition the OpenCL kernels and the GLSL shaders read.

A material is two streams, one of integers and one of floats, each laid out row by row
TABLE_WIDTH texels wide (wide tables such as wallpaper's 31,291 × 11 PDF2 scales would exceed the
16,384-texel height limit as 2D textures of their own). Each stream starts with a header —
sizes and every table's offset — so shaders need no push constants for the layout and any number
of tables costs two samplers (the limit is 16 on Metal).

Both streams are float32 (R32F textures, float buffers): Blender's ``gpu`` module only uploads
float data, and integers are exact in float32 up to 2^24, which ``pack`` checks. (Reinterpreting
int bits as floats would be exact too, but small integers become denormals that some GPUs flush
to zero.)

Device code never spells a slot number: ``defines()`` turns INT_HEADER, FLOAT_HEADER, the codec
ids and the sizes below into ``H_*``, ``F_*``, ``CODEC_*``, ``TABLE_WIDTH``… which
cl/programs.py passes as ``-D`` options and gl/interface.py as ``#define``s / create-info
defines at build time (kernels/include/btf_packed.h and shaders/btf_tables_lib.glsl
``#error`` without them).

Codecs register themselves beside their own code (``register_codec`` at the end of mlvq_pack.py,
dense.py, analytic.py): a codec id and a function that writes the codec's header slots and
tables. ``pack`` dispatches on ``btf.meta.codec`` through that registry.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import UnsupportedBTFError
from ..mapping import BLOCK_SLOT, FILTER_IDS, MAPPING_IDS, MATERIAL_BLOCK_FLOATS
from ..model import BTF, innermost
from ..sampling import btf_importance

TABLE_WIDTH = 4096  # texels per row of both streams
HEADER_INTS = 48  # integer header slots reserved (INT_HEADER uses the first ones)
HEADER_FLOATS = 12  # float header slots reserved
MAGIC = 0xB7F1  # header check value in slot H_MAGIC, exact in float32
MAX_EXACT_INT = 1 << 24

#: Integer header slots in order; device code names slot i ``H_<NAME>`` (H_CODEC = 1, ...).
#: ``f_*`` slots hold an offset into the float stream, the other table slots offsets into the
#: integer stream.
INT_HEADER: tuple[str, ...] = (
    "magic",
    "codec",
    # MLVQ
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
    # MLVQ, the decode's own interleaved copies (mlvq_pack.fast_tables): float-stream offsets
    "f_mlvq6",
    "f_mlvq4",
    "f_mlvq3",
    "f_mlvq2",
    "f_mlvq_ab",
    # dense (shares width and height)
    "n_lights",
    "f_data",
    "n_view_rings",
    "f_view_theta",
    "view_offsets",
    "n_light_rings",
    "f_light_theta",
    "light_offsets",
    # svd (shares width, height, n_lights and the dense ring-grid slots): an int table of
    # (rank, U offset, SV offset) per channel, and the colour transform's 15 floats
    "svd_channels",
    "f_svd_colour",
    # importance sampling of measured codecs (core/sampling/btf_importance.py; 0: none, cosine
    # sampling)
    "f_importance",
    "importance_grid",
    "importance_views",
    # MLVQ, flattened pdf4 → pdf3 (mlvq_pack.fast_tables): float-stream offset
    "f_mlvq43",
)

#: Float header slots in order as (name, number of floats); device code names the first float
#: of each ``F_<NAME>`` (F_ALBEDO = 2 is followed by its green and blue).
FLOAT_HEADER: tuple[tuple[str, int], ...] = (
    ("value_scale", 1),
    ("hdr_value", 1),
    ("albedo", 3),
    ("alpha2", 1),
    ("metallic", 1),
    ("diffuse_roughness", 1),
    ("specular_f0", 1),
)


def _float_slots() -> dict[str, tuple[int, int]]:
    slots, cursor = {}, 0
    for name, size in FLOAT_HEADER:
        slots[name] = (cursor, size)
        cursor += size
    return slots


INT_SLOT = {name: i for i, name in enumerate(INT_HEADER)}
FLOAT_SLOT = _float_slots()  # name → (first slot, size)
assert len(INT_HEADER) <= HEADER_INTS
assert sum(size for _, size in FLOAT_HEADER) <= HEADER_FLOATS


@dataclass
class PackedTables:
    """ints: (rows, TABLE_WIDTH) float32 holding exact integers; floats: (rows, TABLE_WIDTH)
    float32."""

    ints: np.ndarray
    floats: np.ndarray


class TableWriter:
    """What a codec's pack function fills: header slots (``set``) and appended tables
    (``int_table`` / ``float_table`` return the table's offset in its stream)."""

    def __init__(self) -> None:
        self.int_header = np.zeros(HEADER_INTS, dtype=np.int32)
        self.float_header = np.zeros(HEADER_FLOATS, dtype=np.float32)
        self._ints: list[np.ndarray] = []
        self._floats: list[np.ndarray] = []
        self._int_cursor, self._float_cursor = HEADER_INTS, HEADER_FLOATS

    def set(self, **slots: float | Sequence[float]) -> None:
        """Header values by slot name (INT_HEADER or FLOAT_HEADER); a float slot of size k
        takes k values. An unknown name is a KeyError, so a typo cannot pass silently."""
        for name, value in slots.items():
            if name in INT_SLOT:
                self.int_header[INT_SLOT[name]] = int(value)
                continue
            first, size = FLOAT_SLOT[name]
            values = np.asarray(value, dtype=np.float32).ravel()
            if values.size != size:
                raise ValueError(f"header slot {name!r} holds {size} floats, got {values.size}")
            self.float_header[first : first + size] = values

    def int_table(self, table: np.ndarray) -> int:
        flat = np.ascontiguousarray(table).ravel().astype(np.int32)
        offset, self._int_cursor = self._int_cursor, self._int_cursor + flat.size
        self._ints.append(flat)
        return offset

    def float_table(self, table: np.ndarray) -> int:
        flat = np.ascontiguousarray(table).ravel().astype(np.float32)
        offset, self._float_cursor = self._float_cursor, self._float_cursor + flat.size
        self._floats.append(flat)
        return offset

    def align_floats(self, multiple: int) -> None:
        """Pad the float stream so the next table starts at a multiple of ``multiple`` floats
        (a float4 table read as 16-byte rows)."""
        self.float_table(np.zeros(-self._float_cursor % multiple, np.float32))

    def content(self) -> list[np.ndarray]:
        """Everything written so far, headers first (what a digest of the material hashes)."""
        return [self.int_header, self.float_header, *self._ints, *self._floats]

    def finish(self, name: str) -> PackedTables:
        int_stream = np.concatenate([self.int_header, *self._ints])
        float_stream = np.concatenate([self.float_header, *self._floats])
        if int_stream.max() >= MAX_EXACT_INT or int_stream.min() <= -MAX_EXACT_INT:
            raise UnsupportedBTFError(
                f"{name}: index tables too large for the GLSL back end (an index or offset "
                "reaches 2^24); use the OpenCL or numpy back end"
            )
        return PackedTables(layout_stream(int_stream), layout_stream(float_stream))


@dataclass(frozen=True)
class Codec:
    """The one registry record of a codec: its name (``BTFMeta.codec``, the container's
    ``codec`` field), its class (what a container loads through ``from_params``), and where the
    GPU back ends evaluate it, its id (``CODEC_<NAME>`` in device code) and the function
    writing its header slots and tables (None for both: numpy only)."""

    name: str
    cls: type | None
    codec_id: int | None = None
    pack: Callable[[BTF, TableWriter], None] | None = None

    @property
    def on_gpu(self) -> bool:
        return self.codec_id is not None


_CODECS: dict[str, Codec] = {}


def register_codec(
    name: str,
    cls: type | None,
    codec_id: int | None = None,
    pack_fn: Callable[[BTF, TableWriter], None] | None = None,
) -> None:
    """Register a codec; called once, at the end of the codec's own module. ``codec_id`` and
    ``pack_fn`` make it packable for the GPU back ends; ids are device constants: never reuse
    one, never 0 (an empty header)."""
    if (codec_id is None) != (pack_fn is None):
        raise ValueError(f"codec {name!r}: an id and a pack function, or neither")
    if codec_id is not None:
        taken = {c.codec_id: c.name for c in _CODECS.values() if c.name != name and c.on_gpu}
        if codec_id <= 0 or codec_id in taken:
            raise ValueError(f"codec id {codec_id} for {name!r} is invalid or taken by {taken}")
    _CODECS[name] = Codec(name, cls, codec_id, pack_fn)


def codecs() -> dict[str, Codec]:
    """Every registered codec by name (imports the codec modules, so all have registered)."""
    from . import analytic, dense, microgeometry, mlvq_pack, svd  # noqa: F401 - they register

    return dict(_CODECS)


def gpu_codecs() -> dict[str, Codec]:
    """The codecs the GPU back ends evaluate (those with an id and a pack function)."""
    return {name: c for name, c in codecs().items() if c.on_gpu}


def defines() -> dict[str, int]:
    """The layout as build-time defines for OpenCL (``-D``) and GLSL (``#define``): every
    header slot (H_*, F_*), every codec id (CODEC_*), TABLE_WIDTH, the header sizes and the
    magic value; the material block's slots (M_*), size and enumerations (MAPPING_*,
    FILTER_*)."""
    out = {
        "TABLE_WIDTH": TABLE_WIDTH,
        "HEADER_INTS": HEADER_INTS,
        "HEADER_FLOATS": HEADER_FLOATS,
        "PACKED_MAGIC": MAGIC,
    }
    out.update({f"H_{name.upper()}": i for i, name in enumerate(INT_HEADER)})
    out.update({f"F_{name.upper()}": first for name, (first, _) in FLOAT_SLOT.items()})
    out["MATERIAL_BLOCK_FLOATS"] = MATERIAL_BLOCK_FLOATS
    out.update({f"M_{name.upper()}": first for name, (first, _) in BLOCK_SLOT.items()})
    out.update({f"MAPPING_{name}": i for name, i in MAPPING_IDS.items()})
    out.update({f"FILTER_{name}": i for name, i in FILTER_IDS.items()})
    by_id = sorted(gpu_codecs().values(), key=lambda c: c.codec_id)
    out.update({f"CODEC_{c.name.upper()}": c.codec_id for c in by_id})
    return out


def layout_stream(stream: np.ndarray) -> np.ndarray:
    """A flat float stream as (rows, TABLE_WIDTH) float32, zero-padded: the texture layout of
    the packed tables and of the material blocks (element i at column i % TABLE_WIDTH, row
    i // TABLE_WIDTH)."""
    stream = np.asarray(stream, dtype=np.float32).ravel()
    rows = max(1, -(-len(stream) // TABLE_WIDTH))
    out = np.zeros(rows * TABLE_WIDTH, dtype=np.float32)
    out[: len(stream)] = stream
    return out.reshape(rows, TABLE_WIDTH)


def pack(btf: BTF, importance: bool = False) -> PackedTables:
    """A BTF's tables in the packed layout (a device wrapper packs the BTF it wraps).
    ``importance``: a measured codec's sampling table too (core/sampling/btf_importance.py; the
    Sampled
    final render's), built once per BTF object."""
    btf = innermost(btf)
    codec = codecs().get(btf.meta.codec)
    if codec is None or not codec.on_gpu:
        raise UnsupportedBTFError(
            f"the GPU back ends (GLSL, OpenCL) do not evaluate {btf.meta.codec!r} BTFs; "
            "tabulate procedural presets first (synth --tabulate) or use the numpy back end"
        )
    writer = TableWriter()
    writer.set(magic=MAGIC, codec=codec.codec_id, value_scale=btf.meta.value_scale)
    codec.pack(btf, writer)
    if importance and btf_importance.sampled_by_table(btf):
        table = btf_importance.importance_table(btf, content=writer.content)
        writer.set(
            f_importance=writer.float_table(table.packed()),
            importance_grid=table.grid,
            importance_views=table.views,
        )
    return writer.finish(btf.meta.name)

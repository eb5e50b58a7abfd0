"""Reader for BTFbase ``binary.btf``: the original tool's 8-bit quantised form of the MLVQ tables.

The layout was established by comparing the two shared materials' ``binary.btf`` with their text
tables (docs/formats.md has every field). In short:

* a text header: ``4627`` (a magic/version number), ``1`` (materials in the file), the contents
  of ``all_materialInfo.txt`` lines 1–14 (the database path padded with spaces), a blank line and
  the material line (fields padded to 40 characters), each line ending in ``\\n``;
* then 13 binary tables, little endian, in the order of ``BINARY_ORDER``. An index table is
  ``i32 min, i32 max`` and the values ``v − min`` packed LSB first in
  ``bits = bit_length(max − min)`` bits each; a float table is ``f32 min, f32 max, u32 rows,
  u32 cols`` and one byte ``q`` per value, ``v = min + q·(max − min)/256``. Each table's payload
  occupies ``4·(⌊payload bits/32⌋ + 1)`` bytes: 32-bit words and always one more than the
  payload needs whole words for (zero padding). A constant index table (max = min, not in the
  shared files) is read with 0 bits per value, else 1 — whichever parses the whole file.

The text tables of the shared materials hold exactly these dequantised values (to their six
printed decimals), so both forms decode alike (tests/core/test_btfbase_binary.py) — except each
float table's maximum, which the tool wrote as ``q = 256`` and a byte wraps to 0:
``load_binary`` restores it where the bytes allow (core/formats/btfbase_recover.py) and says
which entries stayed ambiguous; ``recover=False`` decodes the bytes as written.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..codecs.btfbase_files import MaterialInfo
from ..codecs.mlvq import MLVQBTF, MLVQParams
from ..errors import BTFFormatError, UnsupportedBTFError
from .btfbase_recover import TableRecovery, recover_table

MAGIC = b"4627"

#: (table, kind, columns): kind "i" index table, "f" float table. The columns of an index table
#: come from the parameterisation (a float table carries its own shape); rows from the counts
#: line of the header (``COUNT_FIELDS``) or, for P6, the material's rows × columns.
BINARY_ORDER = (
    ("pdf6_slices", "i", "cols"),
    ("pdf6_scale", "f", "cols"),
    ("pdf1", "f", "n_beta"),
    ("ab_colors", "f", 2),
    ("index_ab", "i", "n_beta"),
    ("pdf2_slices", "i", "n_alpha"),
    ("pdf2_scale", "f", "n_alpha"),
    ("pdf2_colours", "i", "n_alpha"),
    ("pdf2_indices", "i", 2),
    ("pdf3_slices", "i", "n_theta"),
    ("pdf3_scale", "f", "n_theta"),
    ("pdf4_slices", "i", "n_phi"),
    ("pdf4_scale", "f", "n_phi"),
)

#: Header line 13 (the database's codebook sizes) → the index tables' row counts.
COUNT_FIELDS = {
    "pdf1": 0,
    "ab_colors": 1,
    "index_ab": 2,
    "pdf2_indices": 3,
    "pdf2_slices": 4,
    "pdf2_colours": 5,
    "pdf3_slices": 6,
    "pdf4_slices": 8,
}

#: No table may claim more values than this (a corrupt count must not allocate terabytes):
#: 2²⁸ values is 16 k × 16 k texels, 64× the largest UBO material.
MAX_VALUES = 1 << 28


@dataclass(frozen=True)
class BinaryHeader(MaterialInfo):
    """The text header: what ``all_materialInfo.txt`` says (the parameterisation and the
    material line), plus the codebook counts and where the binary tables start."""

    counts: tuple[int, ...] = ()
    data_offset: int = 0


def is_binary_btf(path: Path) -> bool:
    """Does the file start like a BTFbase ``binary.btf`` (``4627`` then a newline)?"""
    try:
        with open(path, "rb") as fh:
            return fh.read(5) in (MAGIC + b"\n", MAGIC + b"\r")
    except OSError:
        return False


def _line_ints(line: bytes, path: Path, what: str) -> list[int]:
    try:
        return [int(t) for t in line.split()]
    except ValueError:
        raise BTFFormatError(f"{path}: header {what}: expected integers, found {line!r}") from None


def read_header(data: bytes, path: Path) -> BinaryHeader:
    """Parse the text header at the start of ``data`` (the whole file's bytes)."""
    pos = 0
    lines: list[bytes] = []
    # 2 + 14 + blank + material line = 18 lines; each ends in "\n".
    while len(lines) < 18:
        end = data.find(b"\n", pos, pos + 4096)
        if end < 0:
            raise BTFFormatError(f"{path}: the text header is truncated (line {len(lines) + 1})")
        lines.append(data[pos:end].rstrip(b"\r"))
        pos = end + 1
    if lines[0].strip() != MAGIC:
        raise BTFFormatError(f"{path}: not a BTFbase binary.btf (starts {lines[0][:16]!r})")
    if _line_ints(lines[1], path, "line 2")[:1] != [1]:
        raise UnsupportedBTFError(f"{path}: only single-material binary.btf files are supported")
    flags = [_line_ints(ln, path, f"line {i + 4}") for i, ln in enumerate(lines[3:12])]
    if any(len(f) != 1 for f in flags):
        raise BTFFormatError(f"{path}: header lines 4–12 must hold one integer each")
    load, max_materials, all_in_one, use34, compact, n_colour, n_views, n_lights, _ = (
        f[0] for f in flags
    )
    if load != 1 or max_materials != 1 or not all_in_one or use34 or compact:
        raise UnsupportedBTFError(
            f"{path}: only single-material, non-compact databases without PDF34 are supported"
        )
    par = _line_ints(lines[12], path, "line 13 (angle parameterisation)")
    counts = _line_ints(lines[14], path, "line 15 (codebook sizes)")
    if len(par) != 12 or len(counts) < 9:
        raise BTFFormatError(f"{path}: header parameterisation/codebook lines are malformed")
    if lines[16].strip():
        raise BTFFormatError(f"{path}: expected a blank line before the material line")
    material = lines[17].split()
    if len(material) != 9:
        raise BTFFormatError(f"{path}: the material line must have 9 fields")
    ro, co, rows, cols = _line_ints(b" ".join(material[4:8]), path, "material line")
    try:
        hdr_value = float(material[8])
    except ValueError:
        raise BTFFormatError(f"{path}: the material's hdrValue is not a number") from None
    use_cos_beta, n_beta, _, n_alpha, _, n_theta, _, n_phi, *_, code_btf = par
    if code_btf:
        raise UnsupportedBTFError(f"{path}: the 'codeBTF' parameterisation is not supported")
    if n_beta < 3 or n_alpha < 3 or n_theta < 2 or n_phi < 1 or rows <= 0 or cols <= 0:
        raise BTFFormatError(f"{path}: the header's angle steps or material size are invalid")
    if not np.isfinite(hdr_value):
        raise BTFFormatError(f"{path}: the material's hdrValue is not finite")
    return BinaryHeader(
        name=material[0].decode("utf-8", "replace"),
        n_colour=n_colour,
        n_views=n_views,
        n_lights=n_lights,
        use_cos_beta=bool(use_cos_beta),
        n_beta=n_beta,
        n_alpha=n_alpha,
        n_theta=n_theta,
        n_phi=n_phi,
        code_btf=False,  # the binary form has no such flag
        counts=tuple(counts),
        rows_offset=ro,
        cols_offset=co,
        rows=rows,
        cols=cols,
        hdr_value=hdr_value,
        data_offset=pos,
    )


def _payload_bytes(n_bits: int) -> int:
    """Words the tool writes for a payload of ``n_bits``: ⌊n_bits/32⌋ + 1, as bytes."""
    return 4 * (n_bits // 32 + 1)


def _need(data: bytes, pos: int, size: int, path: Path, table: str) -> None:
    if pos + size > len(data):
        raise BTFFormatError(
            f"{path}: truncated in table {table}: needs {size} bytes at offset {pos}, "
            f"the file has {len(data) - pos} left"
        )


def _index_table(data, pos, rows, cols, path, table, constant_bits) -> tuple[np.ndarray, int]:
    n = rows * cols
    if n <= 0 or n > MAX_VALUES:
        raise BTFFormatError(f"{path}: table {table} would hold {rows}×{cols} values")
    _need(data, pos, 8, path, table)
    low, high = (int(v) for v in np.frombuffer(data, "<i4", 2, pos))
    if high < low:
        raise BTFFormatError(f"{path}: table {table}: max {high} < min {low}")
    # A constant table (high == low) was not seen in the shared files: its bit count (0 by
    # bit_length, or a minimum of 1) is whichever makes the whole file parse (read_binary).
    bits = (high - low).bit_length() if high > low else constant_bits
    size = _payload_bytes(n * bits)
    _need(data, pos + 8, size, path, table)
    if bits == 0:
        return np.full((rows, cols), low, dtype=np.int32), pos + 8 + size
    raw = np.frombuffer(data, np.uint8, (n * bits + 7) // 8, pos + 8)
    stream = np.unpackbits(raw, bitorder="little")[: n * bits].reshape(n, bits)
    values = stream.astype(np.int64) @ (np.int64(1) << np.arange(bits, dtype=np.int64))
    values += low
    if values.max() > high:
        raise BTFFormatError(f"{path}: table {table}: a packed value exceeds its stated max")
    return values.astype(np.int32).reshape(rows, cols), pos + 8 + size


@dataclass(frozen=True)
class QuantisedTable:
    """A float table as stored: ``f32 low, f32 high`` and one byte code per value.

    ``values()`` is what the bytes say, ``v = low + q·(high − low)/256`` — where the tool wrote
    a table's maximum as ``q = 256``, that wrapped to 0 and reads as ``low``
    (core/formats/btfbase_recover.py restores what it can)."""

    low: np.float32
    high: np.float32
    codes: np.ndarray  # (rows, cols) uint8

    @property
    def step(self) -> float:
        return (float(self.high) - float(self.low)) / 256.0

    def __len__(self) -> int:
        return len(self.codes)

    def values(self) -> np.ndarray:
        """(rows, cols) float32: the bytes as written (a wrapped maximum reads as ``low``)."""
        q = self.codes.astype(np.float64)
        return (np.float32(self.low) + q * self.step).astype(np.float32)


def _float_table(data, pos, cols, path, table) -> tuple[QuantisedTable, int]:
    _need(data, pos, 16, path, table)
    low, high = (np.float32(v) for v in np.frombuffer(data, "<f4", 2, pos))
    rows, ncols = (int(v) for v in np.frombuffer(data, "<u4", 2, pos + 8))
    if not (np.isfinite(low) and np.isfinite(high)) or high < low:
        raise BTFFormatError(f"{path}: table {table}: range [{low}, {high}] is not finite/ordered")
    if ncols != cols or rows <= 0 or rows * ncols > MAX_VALUES:
        raise BTFFormatError(
            f"{path}: table {table} declares {rows}×{ncols} values, expected n×{cols}"
        )
    n = rows * ncols
    size = _payload_bytes(8 * n)
    _need(data, pos + 16, size, path, table)
    codes = np.frombuffer(data, np.uint8, n, pos + 16).reshape(rows, ncols)
    return QuantisedTable(low, high, codes), pos + 16 + size


def read_binary(path: str | Path) -> tuple[BinaryHeader, dict[str, np.ndarray]]:
    """``binary.btf`` → its header and the 13 MLVQ tables (int32 indices, float32 values),
    named as ``core.codecs.mlvq.TABLE_NAMES``: the bytes as written (wrapped maxima read as
    their table's minimum; ``read_binary_codes`` + btfbase_recover restore them)."""
    head, tables = read_binary_codes(path)
    return head, {k: v.values() if isinstance(v, QuantisedTable) else v for k, v in tables.items()}


def read_binary_codes(
    path: str | Path,
) -> tuple[BinaryHeader, dict[str, np.ndarray | QuantisedTable]]:
    """``binary.btf`` → its header, the 7 index tables (int32) and the 6 float tables as
    stored (``QuantisedTable``: range and byte codes)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise BTFFormatError(f"{path}: cannot read ({exc.strerror})") from None
    head = read_header(data, path)
    try:
        return head, _read_tables(data, head, path, constant_bits=0)
    except BTFFormatError as first:
        try:  # the other reading of constant index tables (see _index_table)
            return head, _read_tables(data, head, path, constant_bits=1)
        except BTFFormatError:
            raise first from None


def _read_tables(data: bytes, head: BinaryHeader, path: Path, constant_bits: int) -> dict:
    columns = {
        "cols": head.cols,
        "n_beta": head.n_beta,
        "n_alpha": head.n_alpha,
        "n_theta": head.n_theta,
        "n_phi": head.n_phi,
    }
    pos = head.data_offset
    tables: dict[str, np.ndarray | QuantisedTable] = {}
    for table, kind, col_key in BINARY_ORDER:
        cols = columns[col_key] if isinstance(col_key, str) else col_key
        if kind == "f":
            tables[table], pos = _float_table(data, pos, cols, path, table)
        else:
            rows = head.rows if table == "pdf6_slices" else head.counts[COUNT_FIELDS[table]]
            tables[table], pos = _index_table(data, pos, rows, cols, path, table, constant_bits)
    if pos != len(data):
        raise BTFFormatError(f"{path}: {len(data) - pos} bytes of trailing data after the tables")
    for table, count in COUNT_FIELDS.items():
        if len(tables[table]) != head.counts[count]:
            raise BTFFormatError(
                f"{path}: table {table} has {len(tables[table])} rows, the header says "
                f"{head.counts[count]}"
            )
    if tables["pdf6_scale"].codes.shape != (head.rows, head.cols):
        raise BTFFormatError(f"{path}: the P6 scale table's shape differs from the material's")
    return tables


def binary_tables(
    path: str | Path, recover: bool = True
) -> tuple[BinaryHeader, dict[str, np.ndarray], dict[str, TableRecovery]]:
    """``binary.btf`` → header, the 13 tables, and per float table what was restored: with
    ``recover`` the wrapped maxima are restored where btfbase_recover's rules allow (ambiguous
    entries at the midpoint), else the bytes are decoded as written."""
    head, stored = read_binary_codes(path)
    tables: dict[str, np.ndarray] = {}
    recovery: dict[str, TableRecovery] = {}
    for name, table in stored.items():
        if not isinstance(table, QuantisedTable):
            tables[name] = table
        elif recover:
            tables[name], recovery[name] = recover_table(name, table, stored["index_ab"])
        else:
            tables[name] = table.values()
    return head, tables, recovery


def params_of(head: BinaryHeader) -> MLVQParams:
    """The codec parameters the header states."""
    return MLVQParams(
        n_beta=head.n_beta,
        n_alpha=head.n_alpha,
        n_theta=head.n_theta,
        n_phi=head.n_phi,
        use_cos_beta=head.use_cos_beta,
        rows_offset=head.rows_offset,
        cols_offset=head.cols_offset,
        hdr_value=head.hdr_value if head.hdr else 1.0,
        n_views=head.n_views,
        n_lights=head.n_lights,
        name=head.name,
    )


def recovery_warnings(path: Path, recovery: dict[str, TableRecovery]) -> list[str]:
    """One warning per table that still holds ambiguous entries (approximate values)."""
    return [f"{path}: {r.describe()}" for r in recovery.values() if not r.recovered]


def load_binary(path: str | Path, recover: bool = True) -> MLVQBTF:
    """``binary.btf`` → an ``MLVQBTF`` (``meta.extra['btfbase_form'] == 'binary'``), its
    wrapped maxima restored unless ``recover`` is False; ``meta.extra['btfbase_recovery']``
    says per float table what was restored and ``meta.extra['warnings']`` names the tables
    left with ambiguous (approximate) entries."""
    path = Path(path)
    head, tables, recovery = binary_tables(path, recover)
    btf = MLVQBTF(params_of(head), tables, source=str(path))
    btf.meta.extra["btfbase_form"] = "binary"
    btf.meta.extra["btfbase_tables"] = dict.fromkeys(tables, "binary")
    if recover:
        btf.meta.extra["btfbase_recovery"] = {k: r.to_json() for k, r in recovery.items()}
        warnings = recovery_warnings(path, recovery)
        if warnings:
            btf.meta.extra["warnings"] = warnings
    return btf

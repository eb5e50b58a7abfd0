"""Reader for the BTFbase MLVQ text tables (the original tool's output directory).

Files: ``all_materialInfo.txt`` (parameterisation and the material line), the shared databases
``all_PDF1Dslice.txt``, ``all_colors.txt``, ``all_indexAB.txt``, ``all_PDF2D{colours,slices,scale,
indices}.txt``, ``all_PDF3D{slices,scale}.txt``, ``all_PDF4D{slices,scale}.txt`` and the
per-material ``<mat>_PDF6D{slices,scale}.txt``. Every table starts with ``rows cols min max``.

Everything is validated on load — counts, shapes, index ranges, finiteness — so that a corrupt,
truncated or inconsistent material fails here with one message naming the file and the problem,
never later inside a renderer.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BTFFormatError, UnsupportedBTFError


@dataclass(frozen=True)
class MaterialInfo:
    """What ``all_materialInfo.txt`` says about the database and its single material."""

    name: str
    n_colour: int
    n_views: int
    n_lights: int
    use_cos_beta: bool
    n_beta: int
    n_alpha: int
    n_theta: int
    n_phi: int
    code_btf: bool
    rows_offset: int
    cols_offset: int
    rows: int
    cols: int
    hdr_value: float

    @property
    def hdr(self) -> bool:
        # The original treats 0 and 1 alike as "LDR, multiplier 1".
        return not (abs(self.hdr_value - 1.0) < 1e-6 or abs(self.hdr_value) < 1e-6)


def _ints(tokens: list[str], path: Path, what: str) -> list[int]:
    try:
        return [int(t) for t in tokens]
    except ValueError:
        raise BTFFormatError(
            f"{path}: {what}: expected integers, found {' '.join(tokens)!r}"
        ) from None


def read_material_info(directory: Path) -> MaterialInfo:
    path = directory / "all_materialInfo.txt"
    if not path.is_file():
        raise BTFFormatError(
            f"{directory}: not a BTFbase material directory (all_materialInfo.txt is missing)"
        )
    lines = [ln.split() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    if len(lines) < 15:
        raise BTFFormatError(f"{path}: expected at least 15 lines, found {len(lines)} (truncated?)")
    load_materials, max_materials, all_in_one, use34, compact = (
        _ints(ln[:1], path, f"line {i + 2}")[0] for i, ln in enumerate(lines[1:6])
    )
    n_colour, n_views, n_lights, _tile = (
        _ints(ln[:1], path, f"line {i + 7}")[0] for i, ln in enumerate(lines[6:10])
    )
    par = _ints(lines[10], path, "line 11 (angle parameterisation)")
    if len(par) != 12:
        raise BTFFormatError(f"{path}: line 11 must hold 12 integers, found {len(par)}")
    if load_materials != 1 or max_materials != 1:
        raise UnsupportedBTFError(
            f"{path}: the database holds {max_materials} materials; only single-material "
            "BTFbase directories are supported"
        )
    if use34 or compact:
        raise UnsupportedBTFError(
            f"{path}: the combined PDF34 view or compact PDF2 representation is not supported"
        )
    if not all_in_one:
        raise UnsupportedBTFError(f"{path}: separate per-material databases are not supported")
    material = lines[14]
    if len(material) != 9:
        raise BTFFormatError(f"{path}: line 15 must be the material line with 9 fields")
    name = material[0]
    if name in (".", "..") or any(c in name for c in "/\\:"):
        raise BTFFormatError(f"{path}: line 15: material name {name!r} is not a plain file name")
    ro, co, pr, pc = _ints(material[4:8], path, "material line offsets and size")
    hdr_value = _float(material[8], path)
    if hdr_value < 0:
        raise BTFFormatError(f"{path}: line 15: the HDR multiplier must be ≥ 0, got {hdr_value}")
    per_material = directory / f"{name}_materialInfo.txt"
    if per_material.is_file():  # the original reads the multiplier from here last
        fields = per_material.read_text(errors="replace").split()
        if len(fields) != 9 or fields[0] != name:
            raise BTFFormatError(f"{per_material}: expected 9 fields starting with {name!r}")
        hdr_value = _float(fields[8], per_material)
        if hdr_value < 0:
            raise BTFFormatError(f"{per_material}: the HDR multiplier must be ≥ 0, got {hdr_value}")
    if min(n_colour, n_views, n_lights) < 0:
        raise BTFFormatError(f"{path}: lines 7–9: colour, view and light counts must be ≥ 0")
    use_cos_beta, n_beta, _, n_alpha, _, n_theta, _, n_phi, *_, code_btf = par
    if n_beta < 3 or n_beta % 2 == 0 or n_alpha < 3 or n_alpha % 2 == 0:
        raise BTFFormatError(f"{path}: beta/alpha step counts must be odd and ≥ 3")
    if n_theta < 2 or n_phi < 1:
        raise BTFFormatError(f"{path}: need ≥ 2 theta and ≥ 1 phi steps")
    if code_btf:
        raise UnsupportedBTFError(f"{path}: the 'codeBTF' parameterisation flag is not supported")
    return MaterialInfo(
        name=name,
        n_colour=n_colour,
        n_views=n_views,
        n_lights=n_lights,
        use_cos_beta=bool(use_cos_beta),
        n_beta=n_beta,
        n_alpha=n_alpha,
        n_theta=n_theta,
        n_phi=n_phi,
        code_btf=bool(code_btf),
        rows_offset=ro,
        cols_offset=co,
        rows=pr,
        cols=pc,
        hdr_value=hdr_value,
    )


def _float(token: str, path: Path) -> float:
    try:
        value = float(token)
    except ValueError:
        raise BTFFormatError(f"{path}: expected a number, found {token!r}") from None
    if not np.isfinite(value):
        raise BTFFormatError(f"{path}: non-finite value {token!r}")
    return value


def read_table(path: Path, integer: bool, cols: int | None = None) -> np.ndarray:
    """One ``rows cols min max`` table → (rows, cols) int32 or float32 array.

    Checked before the values are converted: the header's four fields, the value count it
    declares against the tokens present (no allocation from a header's word alone), and that
    the file ends after a whole number (the original tool ends every table with a newline: a
    file cut inside its last number has the right count but a wrong last value). Errors name
    the file and, for a bad token, its line."""
    if not path.is_file():
        raise BTFFormatError(f"{path}: file is missing")
    data = path.read_bytes()
    tokens = data.split()
    if len(tokens) < 4:
        raise BTFFormatError(f"{path}: header 'rows cols min max' is missing or truncated")
    try:
        rows, ncols = int(tokens[0]), int(tokens[1])
        float(tokens[2]), float(tokens[3])  # min, max: unused, but part of a well-formed header
    except ValueError:
        raise BTFFormatError(
            f"{path}: header must be 'rows cols min max' (two integers, two numbers) on line 1"
        ) from None
    if rows <= 0 or ncols <= 0:
        raise BTFFormatError(f"{path}: header declares an empty table ({rows}×{ncols})")
    if cols is not None and ncols != cols:
        raise BTFFormatError(f"{path}: expected {cols} columns, header says {ncols}")
    body = tokens[4:]
    lines = data.count(b"\n") + (not data.endswith(b"\n"))
    if len(body) != rows * ncols:
        raise BTFFormatError(
            f"{path}: header declares {rows}×{ncols} = {rows * ncols} values, found {len(body)}"
            + (" (truncated?)" if len(body) < rows * ncols else " (trailing data)")
            + f", ending at line {lines}"
        )
    if not data[-1:].isspace():
        raise BTFFormatError(
            f"{path}: line {lines}: the file ends inside a number "
            "(truncated: the original tables end with a newline)"
        )
    try:
        values = np.array(body, dtype=np.float64)
    except ValueError:
        raise BTFFormatError(f"{path}: {_bad_token(data)}") from None
    if not np.all(np.isfinite(values)):
        raise BTFFormatError(f"{path}: {_bad_token(data, finite=True)}")
    if integer:
        if not np.all(values == np.round(values)):
            raise BTFFormatError(f"{path}: an index table contains non-integer values")
        if values.size and (values.min() < -(2**31) or values.max() > 2**31 - 1):
            raise BTFFormatError(f"{path}: an index table holds values beyond 32-bit integers")
        return values.astype(np.int32).reshape(rows, ncols)
    limit = float(np.finfo(np.float32).max)
    if values.size and np.abs(values).max() > limit:
        raise BTFFormatError(f"{path}: {_bad_token(data, limit=limit)}")
    return values.astype(np.float32).reshape(rows, ncols)


def _bad_token(data: bytes, finite: bool = False, limit: float | None = None) -> str:
    """'line N: <token> is not a number' for the first offending token (error path only)."""
    for number, line in enumerate(data.splitlines(), start=1):
        for i, token in enumerate(line.split()):
            if number == 1 and i < 4:
                continue
            try:
                value = float(token)
            except ValueError:
                return f"line {number}: {token[:40].decode(errors='replace')!r} is not a number"
            if finite and not np.isfinite(value):
                return f"line {number}: NaN or infinite value {token.decode(errors='replace')!r}"
            if limit is not None and abs(value) > limit:
                return f"line {number}: {token.decode(errors='replace')!r} is beyond float32"
    return "contains a token that is not a number"


def check_index_range(table: np.ndarray, low: int, high: int, path: Path, target: str) -> None:
    """All entries of ``table`` must lie in [low, high] (inclusive)."""
    if table.size and (table.min() < low or table.max() > high):
        raise BTFFormatError(
            f"{path}: index out of range for {target}: found [{table.min()}, {table.max()}], "
            f"valid [{low}, {high}]"
        )


def table_files(info: MaterialInfo) -> dict[str, tuple[str, bool, int | None]]:
    """Each MLVQ table (``core.codecs.mlvq.TABLE_NAMES``) → its text file's name, whether it
    holds indices, and the column count the parameterisation fixes (None: any)."""
    nb, na, nt, nf = info.n_beta, info.n_alpha, info.n_theta, info.n_phi
    return {
        "pdf1": ("all_PDF1Dslice.txt", False, nb),
        "ab_colors": ("all_colors.txt", False, 2),
        "index_ab": ("all_indexAB.txt", True, nb),
        "pdf2_colours": ("all_PDF2Dcolours.txt", True, na),
        "pdf2_slices": ("all_PDF2Dslices.txt", True, na),
        "pdf2_scale": ("all_PDF2Dscale.txt", False, na),
        "pdf2_indices": ("all_PDF2Dindices.txt", True, 2),
        "pdf3_slices": ("all_PDF3Dslices.txt", True, nt),
        "pdf3_scale": ("all_PDF3Dscale.txt", False, nt),
        "pdf4_slices": ("all_PDF4Dslices.txt", True, nf),
        "pdf4_scale": ("all_PDF4Dscale.txt", False, nf),
        "pdf6_slices": (f"{info.name}_PDF6Dslices.txt", True, None),
        "pdf6_scale": (f"{info.name}_PDF6Dscale.txt", False, None),
    }


def files_of(directory: Path, name: str) -> list[Path]:
    """The files that make up the material (for sizes on disk)."""
    shared = [
        "all_materialInfo.txt",
        "all_PDF1Dslice.txt",
        "all_colors.txt",
        "all_indexAB.txt",
        "all_PDF2Dcolours.txt",
        "all_PDF2Dslices.txt",
        "all_PDF2Dscale.txt",
        "all_PDF2Dindices.txt",
        "all_PDF3Dslices.txt",
        "all_PDF3Dscale.txt",
        "all_PDF4Dslices.txt",
        "all_PDF4Dscale.txt",
    ]
    own = [f"{name}_PDF6Dslices.txt", f"{name}_PDF6Dscale.txt"]
    return [directory / f for f in shared + own]


def text_tables_complete(directory: Path) -> bool:
    """Are all the material's text tables present (``binary.btf`` is the other form)?"""
    try:
        name = read_material_info(directory).name
    except (BTFFormatError, UnsupportedBTFError):
        return False
    return all(f.is_file() for f in files_of(directory, name))

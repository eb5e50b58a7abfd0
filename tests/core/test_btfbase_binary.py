"""BTFbase ``binary.btf``: the layout in docs/formats.md, proved against the text tables."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from helpers import shared_material

from btf_addon.core import btfbase_binary
from btf_addon.core.codecs import load_btf
from btf_addon.core.errors import BTFFormatError
from btf_addon.core.grid import UBO2003
from btf_addon.core.mlvq import MLVQBTF

FLOATS = ("pdf1", "ab_colors", "pdf2_scale", "pdf3_scale", "pdf4_scale", "pdf6_scale")


def _both(material_dir: Path) -> tuple[MLVQBTF, MLVQBTF]:
    return MLVQBTF.from_directory(material_dir), btfbase_binary.load_binary(
        material_dir / "binary.btf"
    )


def test_index_tables_are_identical(material_dir):
    text, binary = _both(material_dir)
    for name, table in text.t.items():
        if table.dtype.kind == "i":
            assert np.array_equal(table, binary.t[name]), name


def test_float_tables_equal_the_text_except_the_wrapped_maximum(material_dir):
    """Every float value equals the text's to its six printed decimals (relative 3e-5 covers
    the smallest P1 values, ~0.015, printed with 6 decimals), except the entries equal to the
    table's maximum: the tool's quantiser writes them as q = 256, which wraps to 0 in a byte,
    so they decode as the table's minimum (docs/formats.md)."""
    text, binary = _both(material_dir)
    for name in FLOATS:
        a = text.t[name].astype(np.float64)
        b = binary.t[name].astype(np.float64)
        wrapped = a == a.max()
        assert 1 <= wrapped.sum() <= 3, name
        assert np.all(b[wrapped] == np.float32(b.min())), name
        np.testing.assert_allclose(b[~wrapped], a[~wrapped], rtol=3e-5, err_msg=name)


def test_decoding_equals_the_text_decode_with_the_wrapped_entries_restored(material_dir, rng):
    """With each float table's wrapped entries set back to the table's max (the one piece of
    information the bytes lost), binary.btf decodes to the text decode: the layout is complete.
    Tolerance 1e-4 relative + 1e-9 absolute: the tables agree to ~3e-5 relative (printing)."""
    text, binary = _both(material_dir)
    tables = dict(binary.t)
    for name in FLOATS:
        a = text.t[name]
        tables[name] = np.where(a == a.max(), a.max(), tables[name]).astype(np.float32)
    restored = MLVQBTF(binary.p, tables)
    th, ph = UBO2003.angles_deg()
    li, vi = rng.integers(0, 81, 4000), rng.integers(0, 81, 4000)
    q = np.column_stack([rng.random((4000, 2)), th[li], ph[li], th[vi], ph[vi]])
    np.testing.assert_allclose(
        restored.evaluate_angles(q), text.evaluate_angles(q), rtol=1e-4, atol=1e-9
    )


def test_a_folder_with_only_binary_btf_loads_it_and_says_so(tmp_path):
    src = shared_material("alu")
    only = tmp_path / "alu"
    only.mkdir()
    shutil.copy(src / "binary.btf", only / "binary.btf")
    btf = load_btf(only)
    assert btf.meta.extra["btfbase_form"] == "binary"
    assert (btf.meta.width, btf.meta.height) == (64, 64)
    assert load_btf(only / "binary.btf").meta.extra["btfbase_form"] == "binary"


def test_a_complete_folder_prefers_the_text_and_incomplete_text_falls_back(tmp_path):
    src = shared_material("alu")
    assert load_btf(src).meta.extra["btfbase_form"] == "text"
    folder = tmp_path / "alu"
    shutil.copytree(src, folder)
    (folder / "all_PDF3Dscale.txt").chmod(0o644)
    (folder / "all_PDF3Dscale.txt").write_text("539 7 0 1\n1 2 3\n")  # truncated
    btf = load_btf(folder)
    assert btf.meta.extra["btfbase_form"] == "binary"
    assert "all_PDF3Dscale.txt" in btf.meta.extra["text_tables_error"]


def _write(tmp_path: Path, data: bytes) -> Path:
    path = tmp_path / "binary.btf"
    path.write_bytes(data)
    return path


def test_hard_cases_end_in_one_clear_error(tmp_path):
    data = (shared_material("alu") / "binary.btf").read_bytes()
    head = btfbase_binary.read_header(data, Path("x"))
    cases = {
        "truncated in table": data[: len(data) - 100],
        "text header is truncated": data[:200],
        "trailing data": data + b"\0" * 8,
        "not a BTFbase binary.btf": b"4628" + data[4:],
        # The P4 count (codebook line, 9th field) at 2^40: refused before allocating.
        "would hold": data.replace(
            b"\n1381 2 5 1723 1645 4 539 0 34 0\n",
            b"\n1381 2 5 1723 1645 4 539 0 1099511627776 0\n",
        ),
    }
    for message, blob in cases.items():
        with pytest.raises(BTFFormatError, match=message):
            btfbase_binary.read_binary(_write(tmp_path, blob))
    # A P6 slot beyond the P4 table: caught by the MLVQ index validation.
    blob = bytearray(data)
    blob[head.data_offset + 4 : head.data_offset + 8] = (999).to_bytes(4, "little")
    with pytest.raises(BTFFormatError):
        btfbase_binary.load_binary(_write(tmp_path, bytes(blob)))

"""BTFbase ``binary.btf``: the layout in docs/formats.md, proved against the text tables."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from helpers import shared_material

from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.errors import BTFFormatError
from btf_addon.core.formats import btfbase_binary
from btf_addon.core.formats.load import load_btf
from btf_addon.core.grid import UBO2003

FLOATS = ("pdf1", "ab_colors", "pdf2_scale", "pdf3_scale", "pdf4_scale", "pdf6_scale")


def _both(material_dir: Path) -> tuple[MLVQBTF, MLVQBTF]:
    """The text tables and binary.btf's bytes as written (no wrapped maximum restored)."""
    return MLVQBTF.from_directory(material_dir), btfbase_binary.load_binary(
        material_dir / "binary.btf", recover=False
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


def test_a_complete_folder_prefers_the_text_and_a_damaged_table_comes_from_binary(tmp_path):
    src = shared_material("alu")
    assert load_btf(src).meta.extra["btfbase_form"] == "text"
    folder = tmp_path / "alu"
    shutil.copytree(src, folder)
    (folder / "all_PDF3Dscale.txt").chmod(0o644)
    (folder / "all_PDF3Dscale.txt").write_text("539 7 0 1\n1 2 3\n")  # truncated
    btf = load_btf(folder)
    assert btf.meta.extra["btfbase_form"] == "text+binary"  # only that table (issue 31)
    assert btf.meta.extra["btfbase_tables"]["pdf3_scale"] == "binary"
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


def _encode_index(values: np.ndarray, bits_if_constant: int) -> bytes:
    """An index table by the documented layout (written here, independently of the reader)."""
    low, high = int(values.min()), int(values.max())
    bits = (high - low).bit_length() if high > low else bits_if_constant
    n = values.size
    payload = np.zeros(4 * (n * bits // 32 + 1), dtype=np.uint8)
    if bits:
        planes = ((values.ravel()[:, None] - low) >> np.arange(bits)) & 1
        packed = np.packbits(planes.astype(np.uint8).ravel(), bitorder="little")
        payload[: len(packed)] = packed
    return np.array([low, high], "<i4").tobytes() + payload.tobytes()


def _encode_float(values: np.ndarray) -> bytes:
    low, high = np.float32(values.min()), np.float32(values.max())
    q = np.round((values.astype(np.float64) - low) / (float(high) - float(low)) * 256)
    payload = np.zeros(4 * (values.size * 8 // 32 + 1), dtype=np.uint8)
    payload[: values.size] = np.clip(q, 0, 255).astype(np.uint8).ravel()  # no wrap here
    head = np.array([low, high], "<f4").tobytes() + np.array(values.shape, "<u4").tobytes()
    return head + payload.tobytes()


@pytest.mark.parametrize("constant_bits", [0, 1])
def test_constant_index_tables_read_either_way(tmp_path, constant_bits):
    """A constant index table (here IndexAB all 0: every β sample uses colour 0) was not in the
    shared files; written with 0 or with 1 bit per value by the documented layout, both parse."""
    data = (shared_material("alu") / "binary.btf").read_bytes()
    head, tables = btfbase_binary.read_binary(shared_material("alu") / "binary.btf")
    tables["index_ab"] = np.zeros_like(tables["index_ab"])
    body = b"".join(
        _encode_float(tables[name]) if kind == "f" else _encode_index(tables[name], constant_bits)
        for name, kind, _ in btfbase_binary.BINARY_ORDER
    )
    path = _write(tmp_path, data[: head.data_offset] + body)
    _, back = btfbase_binary.read_binary(path)
    assert np.all(back["index_ab"] == 0)
    for name, table in tables.items():
        if table.dtype.kind == "i":
            np.testing.assert_array_equal(back[name], table, err_msg=name)
        else:  # re-quantised to this table's own (min, max): within one step (the top one
            # is clipped to 255 rather than wrapped)
            step = (float(table.max()) - float(table.min())) / 256
            np.testing.assert_allclose(back[name], table, atol=step + 1e-6, err_msg=name)

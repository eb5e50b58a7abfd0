"""BTFbase folders read table by table (issue 31): each table from its text file when present
and valid, the rest from binary.btf with its wrapped maxima restored where the bytes allow;
damaged text tables reported by name, never replaced silently."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from helpers import random_queries, shared_material

from btf_addon.core.codecs import btfbase_files
from btf_addon.core.codecs.mlvq import MLVQBTF, TABLE_NAMES
from btf_addon.core.errors import BTFFormatError
from btf_addon.core.formats import btfbase_binary
from btf_addon.core.formats.btfbase_binary import QuantisedTable
from btf_addon.core.formats.btfbase_recover import recover_table
from btf_addon.core.formats.load import load_btf, load_warnings

#: Relative RMSE (over seeded random queries) a table read from binary.btf may add when all
#: its values are recovered: the 8-bit form equals the text to its six printed decimals.
RECOVERED_RMSE = 0.005
N_QUERIES = 50_000


def _rel_rmse(got: np.ndarray, want: np.ndarray) -> float:
    return float(np.sqrt(np.mean((got - want) ** 2)) / np.sqrt(np.mean(want**2)))


def _without(src: Path, dst: Path, *hidden: str) -> Path:
    """``src`` as a folder of links without the ``hidden`` files (the files are not copied:
    the wallpaper folder is 11 MB)."""
    dst.mkdir()
    for f in src.iterdir():
        if f.name not in hidden:
            os.symlink(f, dst / f.name)
    return dst


def _copy(src: Path, dst: Path, *edited: str) -> Path:
    """Links to ``src``'s files except ``edited``, which are writable copies."""
    _without(src, dst, *edited)
    for name in edited:
        shutil.copy(src / name, dst / name)
        (dst / name).chmod(0o644)
    return dst


@pytest.mark.parametrize("material", ["alu", "wallpaper"])
def test_hiding_each_text_table_in_turn(tmp_path, material):
    """Every table hidden in turn: the folder loads, the table comes from binary.btf, and the
    decode stays within RECOVERED_RMSE of the full text decode when binary.btf gives all its
    values back; a table left with ambiguous entries (warned) stays below binary.btf alone
    decoded as written (today's figure). The measured errors are in docs/formats.md."""
    src = shared_material(material)
    info = btfbase_files.read_material_info(src)
    full = load_btf(src)
    assert full.meta.extra["btfbase_form"] == "text" and not load_warnings(full)
    q = random_queries(np.random.default_rng(31), N_QUERIES)
    want = full.evaluate_angles(q)
    as_written = btfbase_binary.load_binary(src / "binary.btf", recover=False)
    binary_only = _rel_rmse(as_written.evaluate_angles(q), want)
    errors = {}
    for table, (file, _, _) in btfbase_files.table_files(info).items():
        folder = _without(src, tmp_path / table, file)
        btf = load_btf(folder)
        extra = btf.meta.extra
        assert extra["btfbase_form"] == "text+binary"
        assert [k for k, v in extra["btfbase_tables"].items() if v == "binary"] == [table]
        assert "text_tables_error" not in extra  # missing is not damaged
        errors[table] = error = _rel_rmse(btf.evaluate_angles(q), want)
        recovery = extra["btfbase_recovery"].get(table)
        if recovery is None or recovery["ambiguous"] == 0:  # an index table, or all restored
            assert error < RECOVERED_RMSE, (table, error)
            assert not load_warnings(btf)
        else:
            assert error < binary_only, (table, error, binary_only)
            assert any(table in w and "ambiguous" in w for w in load_warnings(btf))
    # P1 (rows sum to 1) and the P2 scales (smooth over α) are restored in both materials.
    assert errors["pdf1"] < 1e-4 and errors["pdf2_scale"] < 1e-4, errors


def test_the_thesis_gallery_case_only_the_p2_scales_missing(tmp_path):
    """Three gallery materials ship every text table but all_PDF2Dscale.txt: their P2 scales
    come from binary.btf with every wrapped maximum restored (no warning)."""
    src = shared_material("alu")
    btf = load_btf(_without(src, tmp_path / "alu", "all_PDF2Dscale.txt"))
    recovery = btf.meta.extra["btfbase_recovery"]
    assert list(recovery) == ["pdf2_scale"]
    assert recovery["pdf2_scale"]["maxima"] >= 1 and recovery["pdf2_scale"]["ambiguous"] == 0
    np.testing.assert_allclose(
        btf.t["pdf2_scale"], MLVQBTF.from_directory(src).t["pdf2_scale"], rtol=3e-5
    )
    assert not load_warnings(btf)


def test_recovered_tables_equal_the_text_tables(material_dir):
    """Per float table of binary.btf: restored entries equal the text (to its printed
    decimals); ambiguous ones lie at the midpoint, at most (max − min)/2 off; P1 by its row
    sums (exact), never ambiguous."""
    text = MLVQBTF.from_directory(material_dir)
    _, tables, recovery = btfbase_binary.binary_tables(material_dir / "binary.btf")
    assert recovery["pdf1"].exact == recovery["pdf1"].candidates
    for name, rec in recovery.items():
        a, b = text.t[name].astype(np.float64), tables[name].astype(np.float64)
        off = ~np.isclose(a, b, rtol=3e-5, atol=1e-9)
        assert off.sum() == rec.ambiguous, name
        # float32 midpoints: one rounding of the values' magnitude
        assert np.all(np.abs(a - b)[off] <= rec.max_error + 1e-6 * np.abs(a).max()), name


# --- the rules, on tables written here ---------------------------------------------------
def _quantised(values: np.ndarray) -> QuantisedTable:
    """The tool's quantiser: q = (v − min)·256/(max − min), the maximum wrapping to 0."""
    low, high = np.float32(values.min()), np.float32(values.max())
    q = np.round((values - float(low)) / (float(high) - float(low)) * 256).astype(np.int64)
    return QuantisedTable(low, high, (q % 256).astype(np.uint8))


def test_row_sums_restore_p1_exactly(rng):
    rows = rng.random((40, 11)) + 0.2
    rows[7, 3] = 5.0  # the maximum, in one row
    rows /= rows.sum(axis=1, keepdims=True)
    rows[12, 0] = rows.min() * 0.5  # a clear minimum elsewhere (the row no longer sums to 1)
    rows[12] /= rows[12].sum()
    table = _quantised(rows)
    values, rec = recover_table("pdf1", table)
    assert rec.exact == rec.candidates and rec.maxima == 1 and rec.ambiguous == 0
    assert values[7, 3] == table.high


def test_a_smooth_table_restores_a_maximum_inside_a_peak():
    alpha = np.linspace(-1, 1, 11)
    rows = np.array([500 + 1000 * np.exp(-4 * (alpha - alpha[i % 11]) ** 2) for i in range(30)])
    rows[5, 5] *= 1.01  # the peak of one curve: the table's maximum
    table = _quantised(rows)
    values, rec = recover_table("pdf2_scale", table)
    assert rec.maxima == 1 and rec.ambiguous == 0
    assert values[5, 5] == table.high


def test_isolated_extremes_stay_ambiguous_at_the_midpoint():
    """Scales near 1 whose minimum and maximum are both lone spikes (the P4 case): neither
    reading is a smooth one, the jump readings would contradict the stored range, so both
    entries are ambiguous and take the midpoint."""
    rows = np.ones((8, 16))
    rows[3, 2], rows[3, 9] = 0.97, 1.03
    table = _quantised(rows)
    values, rec = recover_table("pdf4_scale", table)
    assert rec.ambiguous == 2 and rec.maxima == 0
    assert values[3, 2] == values[3, 9] == np.float32((0.97 + 1.03) / 2)
    assert rec.max_error == pytest.approx(0.03, rel=1e-5)


def test_counting_settles_the_last_candidate():
    """The minimum ends a smooth row (its jump reading settles it); the maximum is a lone
    spike neither reading fits: as the one candidate left, and no maximum found yet, it is
    the maximum."""
    rows = np.full((6, 11), 1000.0) + np.linspace(0, 5, 11)
    rows[2] = np.linspace(1000, 900, 11)  # the minimum at (2, 10)
    rows[4, 5] = 1100.0  # the maximum
    table = _quantised(rows)
    values, rec = recover_table("pdf2_scale", table)
    assert (rec.candidates, rec.maxima, rec.ambiguous) == (2, 1, 0)
    assert values[4, 5] == table.high and values[2, 10] == table.low


def test_colours_are_judged_by_the_colours_their_runs_meet():
    """A colour's neighbours are the colours IndexAB's runs over β interpolate it with: the
    Cr of colour 1 meets Cr values near 140 (so 140, the maximum, not 110); its Cb is then
    the minimum by counting. Without the runs, nothing orders the colours: both ambiguous."""
    colours = np.array(
        [[120.0, 138.0], [110.0, 140.0], [124.0, 139.0], [119.0, 137.5], [121.0, 136.0]]
    )
    runs = np.array([[0, 1, 1, 2, 3], [4, 1, 0, 0, 2], [3, 3, 4, 2, 0]])
    table = _quantised(colours)  # min 110 at (1, 0), max 140 at (1, 1)
    values, rec = recover_table("ab_colors", table, runs)
    assert (rec.candidates, rec.maxima, rec.ambiguous) == (2, 1, 0)
    assert values[1, 1] == table.high and values[1, 0] == table.low
    values, rec = recover_table("ab_colors", table)
    assert (rec.candidates, rec.ambiguous) == (2, 2)
    assert values[1, 0] == values[1, 1] == np.float32(125.0)


# --- damaged text: reported, not silently replaced ---------------------------------------
def _first_value(text: str, value: str) -> str:
    """The table's first value (line 2, first token) replaced."""
    lines = text.split("\n")
    lines[1] = " ".join([value, *lines[1].split()[1:]])
    return "\n".join(lines)


@pytest.mark.parametrize(
    ("file", "damage", "problem"),
    [
        ("all_PDF3Dscale.txt", lambda t: t[: len(t) // 2], "truncated"),
        ("all_PDF4Dscale.txt", lambda t: t.replace("1.000012", "1.0x0012", 1), "is not a number"),
        ("all_PDF4Dslices.txt", lambda t: _first_value(t, "9999"), "index out of range"),
    ],
)
def test_a_damaged_table_is_named_in_the_warnings(tmp_path, file, damage, problem):
    src = shared_material("alu")
    folder = _copy(src, tmp_path / "alu", file)
    path = folder / file
    path.write_text(damage(path.read_text()))
    btf = load_btf(folder)
    warnings = load_warnings(btf)
    assert len(warnings) >= 1 and file in warnings[0] and problem in warnings[0], warnings
    assert "binary.btf" in warnings[0]
    assert file in btf.meta.extra["text_tables_error"]
    files = btfbase_files.table_files(btfbase_files.read_material_info(src))
    tables = btf.meta.extra["btfbase_tables"]
    assert [files[k][0] for k, v in tables.items() if v == "binary"] == [file]


def test_without_binary_btf_damage_is_an_error(tmp_path):
    src = shared_material("alu")
    folder = _copy(src, tmp_path / "alu", "all_PDF3Dscale.txt")
    (folder / "binary.btf").unlink()
    (folder / "all_PDF3Dscale.txt").write_text("539 7 0 1\n1 2 3\n")
    with pytest.raises(BTFFormatError, match=r"all_PDF3Dscale\.txt.*truncated"):
        load_btf(folder)


def test_the_binary_form_on_request(tmp_path):
    src = shared_material("alu")
    btf = load_btf(src, prefer_binary=True)
    assert btf.meta.extra["btfbase_form"] == "binary"
    assert set(btf.meta.extra["btfbase_tables"].values()) == {"binary"}
    assert set(btf.meta.extra["btfbase_recovery"]) == {
        "pdf1", "ab_colors", "pdf2_scale", "pdf3_scale", "pdf4_scale", "pdf6_scale"
    }  # fmt: skip
    folder = _without(src, tmp_path / "alu", "binary.btf")
    with pytest.raises(BTFFormatError, match=r"no binary\.btf"):
        load_btf(folder, prefer_binary=True)


def test_another_parameterisation_is_not_mixed(tmp_path):
    """Text tables of another angular grid than binary.btf's (a folder mixed up by hand):
    binary.btf is read alone, with a warning."""
    src = shared_material("alu")
    folder = _copy(src, tmp_path / "alu", "all_materialInfo.txt")
    (folder / "all_PDF2Dscale.txt").unlink()
    info = folder / "all_materialInfo.txt"
    info.write_text(info.read_text().replace("1 11 0 11 0 7 0 16", "1 11 0 11 0 7 0 8", 1))
    btf = load_btf(folder)
    assert btf.meta.extra["btfbase_form"] == "binary"
    assert any("parameterisation" in w for w in load_warnings(btf))


def test_all_tables_are_named():
    assert set(btfbase_files.table_files(_info()).keys()) == set(TABLE_NAMES)


def _info() -> btfbase_files.MaterialInfo:
    return btfbase_files.read_material_info(shared_material("alu"))

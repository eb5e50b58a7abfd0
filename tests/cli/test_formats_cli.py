"""info / convert / eval on the formats of issue 15, as a user runs them (subprocesses)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from helpers import run_cli, shared_material

from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.load import load_btf
from btf_addon.core.grid import uniform_ring_grid


def test_info_says_a_folder_was_read_from_binary_btf(tmp_path):
    folder = tmp_path / "alu"
    folder.mkdir()
    shutil.copy(shared_material("alu") / "binary.btf", folder / "binary.btf")
    out = json.loads(run_cli("info", folder).stdout)
    assert out["format"] == "btfbase-mlvq-binary" and out["spatial_size"] == [64, 64]
    assert out["bytes_on_disk"] == 80_905
    assert json.loads(run_cli("info", shared_material("alu")).stdout)["format"] == (
        "btfbase-mlvq-text"
    )


def test_convert_dense_to_ubo2014_btf_and_back_to_btfm(tmp_path, rng):
    dense = tabulate(
        woven(texels=4, fine_per_texel=4), uniform_ring_grid(20.0), uniform_ring_grid(15.0)
    )
    write_container(tmp_path / "d.btfm", dense)
    proc = run_cli("convert", tmp_path / "d.btfm", tmp_path / "d.btf", "--rank", "6")
    errors = json.loads(proc.stdout)["relative_truncation_error_yuv"]
    assert len(errors) == 3 and max(errors) < 0.2
    info = json.loads(run_cli("info", tmp_path / "d.btf").stdout)
    assert info["format"] == "ubo2014-dfmf" and info["codec"] == "svd"
    run_cli("convert", tmp_path / "d.btf", tmp_path / "s.btfm")
    q = np.column_stack([rng.random((300, 2)), rng.random((300, 4)) * [80, 360, 80, 360]])
    np.save(tmp_path / "q.npy", q.astype(np.float32))
    run_cli(
        "eval", tmp_path / "s.btfm", "--queries", tmp_path / "q.npy", "--out", tmp_path / "v.npy"
    )
    got = np.load(tmp_path / "v.npy")
    # the .btfm holds exactly the .btf's (half-precision) factors: equal up to float32 output
    want = load_btf(tmp_path / "d.btf").evaluate_angles(q.astype(np.float32))
    np.testing.assert_allclose(got, want, atol=1e-6)
    assert np.abs(got - dense.evaluate_angles(q.astype(np.float32))).max() < 0.2 * want.max()


def _linked(src, dst, *edited):
    """``src`` as links, the ``edited`` files as writable copies."""
    dst.mkdir()
    for f in src.iterdir():
        if f.name in edited:
            shutil.copy(f, dst / f.name)
            (dst / f.name).chmod(0o644)
        else:
            (dst / f.name).symlink_to(f)
    return dst


def test_info_names_a_damaged_table_and_the_binary_form_on_request(tmp_path):
    """Issue 31: a damaged text table is read from binary.btf and named (text_tables_error,
    warnings); --prefer-binary reads binary.btf alone; convert prints the warnings."""
    folder = _linked(shared_material("alu"), tmp_path / "alu", "all_PDF3Dscale.txt")
    (folder / "all_PDF3Dscale.txt").write_text("539 7 0 1\n1 2 3\n")
    out = json.loads(run_cli("info", folder).stdout)
    assert out["format"] == "btfbase-mlvq-text+binary"
    assert "all_PDF3Dscale.txt" in out["text_tables_error"]
    assert out["tables_from_binary"] == ["pdf3_scale"]
    assert any("all_PDF3Dscale.txt" in w for w in out["warnings"])
    proc = run_cli("convert", folder, tmp_path / "a.btfm")
    assert "warning:" in proc.stderr and "all_PDF3Dscale.txt" in proc.stderr

    out = json.loads(run_cli("info", shared_material("alu"), "--prefer-binary").stdout)
    assert out["format"] == "btfbase-mlvq-binary" and out["bytes_on_disk"] == 80_905
    assert out["binary_recovery"]["pdf1"]["ambiguous"] == 0
    run_cli("convert", shared_material("alu"), tmp_path / "b.btfm", "--prefer-binary")
    restored = load_btf(tmp_path / "b.btfm").tables()["pdf2_scale"].max()  # the wrap restored
    text = load_btf(shared_material("alu")).tables()["pdf2_scale"].max()
    assert restored == pytest.approx(text, rel=1e-6)  # f32 max vs its six printed decimals


def test_a_converted_material_is_no_bigger_than_its_binary_btf(tmp_path, rng):
    """Issue 31: the compact .btfm (version 2) of the text tables is smaller than the tool's
    own 8-bit binary.btf, and decodes exactly as the text tables do."""
    for name in ("alu", "wallpaper"):
        src = shared_material(name)
        dst = tmp_path / f"{name}.btfm"
        run_cli("convert", src, dst)
        assert dst.stat().st_size <= (src / "binary.btf").stat().st_size, name
        out = json.loads(run_cli("info", dst).stdout)
        assert out["format"] == "btfm-container-v2"
        q = rng.random((300, 6)) * [1, 1, 90, 360, 90, 360]
        np.testing.assert_array_equal(
            load_btf(dst).evaluate_angles(q), load_btf(src).evaluate_angles(q)
        )

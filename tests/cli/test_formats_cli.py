"""info / convert / eval on the formats of issue 15, as a user runs them (subprocesses)."""

from __future__ import annotations

import json
import shutil

import numpy as np
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

"""``python -m btf_addon compress``: report, output file, Ctrl-C leaves nothing behind.

The input is a 4×4-texel synthetic dense BTF with small codebooks: ~2 s per encode."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from btf_addon.cli.main import main
from btf_addon.core.encoders import metrics
from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.load import load_btf

ROOT = Path(__file__).resolve().parents[2]
KNOBS = ["--k1", "24", "--k2", "24", "--k3", "8", "--k4", "4", "--colours", "4"]


@pytest.fixture(scope="module")
def source(tmp_path_factory) -> Path:
    sys.path.insert(0, str(ROOT / "tests"))
    from core.test_encoder_mlvq import synthetic

    return write_container(tmp_path_factory.mktemp("src") / "synthetic.btfm", synthetic())


def test_compress_writes_a_material_and_reports_its_numbers(source, tmp_path, capsys):
    out = tmp_path / "out.btfm"
    assert main(["compress", str(source), "-o", str(out), "--codec", "mlvq", *KNOBS]) == 0
    report = json.loads(capsys.readouterr().out)
    enc = load_btf(out)
    assert enc.meta.codec == "mlvq" and report["output"] == str(out)
    assert report["file_bytes"] == out.stat().st_size
    # Issue 31: the ratio that means the file on disk.
    assert report["file_ratio"] == pytest.approx(report["raw_bytes"] / report["file_bytes"], 1e-3)
    assert report["raw_bytes"] == 81 * 81 * 4 * 4 * 3
    assert report["packed_ratio"] == pytest.approx(
        report["raw_bytes"] / report["packed_bytes"], rel=1e-3
    )
    assert report["codebooks"]["pdf1"] <= 24 and report["settings"]["k2"] == 24
    # The reported PSNR is the written file's, measured again here at the same texels.
    src = load_btf(source)
    again = metrics.psnr(src, enc, metrics.texel_subset(4, 4, report["psnr_texels"]))
    assert report["psnr_db"] == pytest.approx(again, abs=1e-3)
    assert report["ssim"] == pytest.approx(metrics.ssim(src, enc), abs=1e-5)
    assert report["psnr_db"] >= 29.0  # measured 30.8 dB (tests/core/test_encoder_mlvq.py)


def test_bad_knob_is_one_clear_error(source, tmp_path, capsys):
    out = tmp_path / "bad.btfm"
    assert main(["compress", str(source), "-o", str(out), "--k2", "0"]) == 2
    assert "k2 must be at least 1" in capsys.readouterr().err
    assert not out.exists()


def test_ctrl_c_during_encoding_leaves_no_file(source, tmp_path):
    out = tmp_path / "cut.btfm"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "btf_addon", "compress", str(source), "-o", str(out)],
        cwd=tmp_path,
        env=env,
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    # Default codebooks on 4×4 texels: seconds of k-means; interrupt once level 2 starts.
    for line in proc.stderr:
        if "level 2" in line:
            proc.send_signal(signal.SIGINT)
            break
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "interrupted" in err
    assert list(tmp_path.iterdir()) == []  # neither the file nor a temporary


def test_nan_free_output_from_a_black_material(tmp_path, capsys):
    from btf_addon.core.codecs.dense import DenseBTF

    src = write_container(
        tmp_path / "black.btfm", DenseBTF(np.zeros((81, 81, 1, 2, 3), np.float32), name="b")
    )
    out = tmp_path / "black_mlvq.btfm"
    assert main(["compress", str(src), "-o", str(out), *KNOBS]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["psnr_db"] is None  # identical (all zero): infinite PSNR, reported as null
    assert np.all(load_btf(out).evaluate_angles(np.full((4, 6), 30.0)) == 0)


def test_train_texels_knob_reaches_the_encoder(source, tmp_path, capsys):
    out = tmp_path / "sub.btfm"
    args = ["compress", str(source), "-o", str(out), *KNOBS, "--train-texels", "4"]
    assert main(args) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["settings"]["train_texels"] == 4
    assert np.all(load_btf(out).tables()["pdf6_slices"] > 0)  # all 16 texels encoded


def test_training_knobs_reach_the_encoder(source, tmp_path, capsys):
    """--train-per-code and --iterations (the wallpaper run's knobs, docs/accuracy.md) reach
    the settings; a negative one is one clear error and no file."""
    out = tmp_path / "train.btfm"
    args = ["compress", str(source), "-o", str(out), *KNOBS]
    assert main([*args, "--train-per-code", "2", "--iterations", "2", "--no-psnr"]) == 0
    settings = json.loads(capsys.readouterr().out)["settings"]
    assert (settings["train_per_code"], settings["iterations"]) == (2, 2)
    bad = tmp_path / "bad.btfm"
    assert main(["compress", str(source), "-o", str(bad), "--iterations", "-1"]) == 2
    assert "must not be negative" in capsys.readouterr().err
    assert not bad.exists()

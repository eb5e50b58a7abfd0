"""``python -m btf_addon compress --codec svd``: report, output file, knobs, Ctrl-C.

The input is the 4×4-texel synthetic dense BTF of tests/core/test_encoder_mlvq.py on the
UBO2003 grid: the encode (a 16 × 16 texel Gram) takes ~0.1 s, the PSNR/SSIM ~1.5 s."""

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


@pytest.fixture(scope="module")
def source(tmp_path_factory) -> Path:
    sys.path.insert(0, str(ROOT / "tests"))
    from core.test_encoder_mlvq import synthetic

    data = synthetic().data.copy()
    data[:, :, 1, 2] *= np.linspace(0.5, 1.5, 81)[None, :, None]  # more than rank 1 per channel
    from btf_addon.core.codecs.dense import DenseBTF

    return write_container(tmp_path_factory.mktemp("src") / "syn.btfm", DenseBTF(data, name="s"))


@pytest.mark.parametrize("colour, model", [("rgb", 0), ("yuv", 1)])
def test_compress_svd_writes_the_material_and_reports_its_numbers(
    source, tmp_path, capsys, colour, model
):
    out = tmp_path / "out.btfm"
    args = ["compress", str(source), "-o", str(out), "--codec", "svd", "--rank", "2,1,1"]
    assert main([*args, "--colour-space", colour]) == 0
    report = json.loads(capsys.readouterr().out)
    enc = load_btf(out)
    assert enc.meta.codec == "svd" and enc.ranks == (2, 1, 1) and enc.p.colour_model == model
    assert report["ranks"] == [2, 1, 1] and report["settings"]["colour_space"] == colour
    assert report["raw_bytes"] == 81 * 81 * 4 * 4 * 3
    assert report["stored_bytes"] == sum(a.nbytes for a in enc.tables().values())
    assert report["float32_ratio"] == pytest.approx(4 * report["stored_ratio"], rel=1e-3)
    # The reported PSNR and SSIM are the written file's, measured again here.
    src = load_btf(source)
    again = metrics.psnr(src, enc, metrics.texel_subset(4, 4, report["psnr_texels"]))
    assert report["psnr_db"] == pytest.approx(again, abs=1e-3)
    assert report["ssim"] == pytest.approx(metrics.ssim(src, enc), abs=1e-5)
    assert 20.0 < report["psnr_db"] < 100.0  # lossy but close: one texel's extra component


def test_one_rank_for_all_channels(source, tmp_path, capsys):
    out = tmp_path / "r3.btfm"
    assert main(["compress", str(source), "-o", str(out), "--codec", "svd", "--rank", "3"]) == 0
    assert json.loads(capsys.readouterr().out)["ranks"] == [3, 3, 3]
    assert load_btf(out).ranks == (3, 3, 3)


def test_factor_bits_give_the_packed_ratio(source, tmp_path, capsys):
    out = tmp_path / "q.btfm"
    args = ["compress", str(source), "-o", str(out), "--codec", "svd", "--rank", "2"]
    assert main([*args, "--factor-bits", "8"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["settings"]["factor_bits"] == 8
    # 8 of 32 bits per factor plus a min/max per column: just under 4× the stored ratio.
    assert 3.9 * report["stored_ratio"] < report["packed_ratio"] < 4 * report["stored_ratio"]


@pytest.mark.parametrize(
    "rank, message", [("0", "rank must be"), ("2,2", "one integer or three"), ("x", "three")]
)
def test_bad_rank_is_one_clear_error(source, tmp_path, capsys, rank, message):
    out = tmp_path / "bad.btfm"
    code = main(["compress", str(source), "-o", str(out), "--codec", "svd", "--rank", rank])
    assert code == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_ctrl_c_before_the_write_leaves_no_file(source, tmp_path):
    """SIGINT once the Gram accumulation starts: it lands in the encode or in the PSNR that
    follows (together ~2 s here), both before the one atomic write."""
    src = source
    work = tmp_path / "work"
    work.mkdir()
    out = work / "cut.btfm"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "btf_addon", "compress", str(src), "-o", str(out), "--codec", "svd"],
        cwd=work,
        env=env,
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    for line in proc.stderr:
        if "Gram" in line:
            proc.send_signal(signal.SIGINT)
            break
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "interrupted" in err
    assert list(work.iterdir()) == []  # neither the file nor a temporary

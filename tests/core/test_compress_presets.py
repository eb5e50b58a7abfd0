"""Compress BTF in Blender speaks in words (issue 32 item 3): the report gives PSNR and SSIM as
the command line measures them and a ratio that means the file on disk; quality presets
(Smallest / Balanced / Best Quality) choose the codebook sizes, which stay under Advanced.
Small synthetic input (4×4 texels, small codebooks): a few seconds."""

from __future__ import annotations

import json
import re

import pytest
from helpers import run_cli

bpy = pytest.importorskip("bpy")

from btf_addon.blender.tools import compress as op  # noqa: E402
from btf_addon.core.encoders.mlvq import MLVQSettings  # noqa: E402
from btf_addon.core.formats.container import write_container  # noqa: E402

SMALL = dict(k1=24, k2=24, k3=8, k4=4)


@pytest.fixture(scope="module")
def registered():
    """This checkout's operator for the module; the installed extension's is put back after."""
    installed = getattr(bpy.types, op.BTF_OT_compress.__name__, None)
    op.register()
    yield
    op.unregister()
    if installed is not None:
        bpy.utils.register_class(installed)


@pytest.fixture
def source(tmp_path):
    from core.test_encoder_mlvq import synthetic

    return write_container(tmp_path / "src.btfm", synthetic())


def test_the_report_gives_psnr_ssim_and_the_files_own_ratio(source, tmp_path):
    out = tmp_path / "out.btfm"
    job = op.Job(str(source), out, MLVQSettings(**SMALL))
    job.thread.start()
    job.thread.join(timeout=120)
    assert job.error is None, job.error
    text = job.summary
    psnr = float(re.search(r"PSNR ([\d.]+) dB", text).group(1))
    ssim = float(re.search(r"SSIM ([\d.]+)", text).group(1))
    ratio = float(re.search(r"(\d+)× smaller than the measured data", text).group(1))
    raw = 81 * 81 * 4 * 4 * 3  # 81 × 81 directions per texel, 3 bytes: BTFbase's count
    assert ratio == round(raw / out.stat().st_size)  # the file on disk, not a layout
    # The same figures as the command line's report of the same encode (its own code path).
    cli = run_cli(
        "compress", source, "-o", tmp_path / "cli.btfm", "--k1", "24", "--k2", "24",
        "--k3", "8", "--k4", "4",
    )  # fmt: skip
    report = json.loads(cli.stdout[cli.stdout.index("{") :])
    assert psnr == pytest.approx(report["psnr_db"], abs=0.05)  # shown with one decimal
    assert ssim == pytest.approx(report["ssim"], abs=5e-4)  # shown with three


@pytest.mark.parametrize(
    ("given", "expected"),
    [
        ({}, op.PRESETS["BALANCED"]),
        ({"preset": "SMALLEST"}, op.PRESETS["SMALLEST"]),
        ({"preset": "BEST"}, op.PRESETS["BEST"]),
        ({"preset": "CUSTOM", **SMALL}, (24, 24, 8, 4)),
        (SMALL, (24, 24, 8, 4)),  # a script's sizes without a preset: its own sizes
        ({"preset": "SMALLEST", **SMALL}, op.PRESETS["SMALLEST"]),  # the preset wins
    ],
)
def test_presets_choose_the_codebooks(registered, source, tmp_path, monkeypatch, given, expected):
    used = []

    def encode(btf, settings, progress, assign=None):
        used.append((settings.k1, settings.k2, settings.k3, settings.k4))
        raise op.CancelledError  # the choice is all this test needs

    monkeypatch.setattr(op, "encode_mlvq", encode)
    bpy.ops.btf.compress(filepath=str(source), output=str(tmp_path / "o.btfm"), **given)
    assert used == [tuple(expected)]


def test_presets_order_the_codebooks():
    small, balanced, best = (op.PRESETS[k] for k in ("SMALLEST", "BALANCED", "BEST"))
    assert all(a < b < c for a, b, c in zip(small, balanced, best, strict=True))
    defaults = MLVQSettings()
    assert balanced == (defaults.k1, defaults.k2, defaults.k3, defaults.k4)

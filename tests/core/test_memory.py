"""The memory model (core/memory.py): sizes that fit complete under a memory cap, sizes that do
not are refused up front with a message, before the heavy work (and before Blender) starts.

Caps are real: the command runs in a subprocess under ``RLIMIT_AS`` (address space), so a
command that allocated beyond its estimate would die with MemoryError (exit 1) instead of
completing, and a refusal that came late would not come within seconds.
"""

from __future__ import annotations

import resource
import struct
import subprocess
import sys
import time

import numpy as np
import pytest
from helpers import ROOT, cli_env

from btf_addon.core import memory
from btf_addon.core.errors import BTFError
from btf_addon.core.formats.imageio import write_exr

#: Address-space cap for the "completes" side: the interpreter with numpy and OpenEXR maps
#: ~130 MB before any work, and each completing case below is estimated at ≤ 700 MB.
CAP = 1536 * memory.MIB


def run_capped(*args, cap=CAP, timeout=120):
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "btf_addon", *map(str, args)],
        cwd=ROOT,
        env=cli_env(),
        capture_output=True,
        text=True,
        preexec_fn=limit,
        timeout=timeout,
        check=False,
    )
    return proc, time.perf_counter() - t0


@pytest.fixture(scope="module")
def lambertian(tmp_path_factory):
    path = tmp_path_factory.mktemp("mem") / "l.btfm"
    subprocess.run(
        [sys.executable, "-m", "btf_addon", "synth", "lambertian", "-o", path],
        cwd=ROOT,
        env=cli_env(),
        check=True,
    )
    return path


def test_sizes_parse_and_budget_takes_the_smallest_limit(monkeypatch):
    assert memory.parse_size("512M") == 512 * memory.MIB
    assert memory.parse_size("1.5G") == int(1.5 * memory.GIB)
    assert memory.parse_size("2048") == 2048
    for bad in ("", "-1G", "lots", "0"):
        with pytest.raises(BTFError):
            memory.parse_size(bad)
    monkeypatch.setenv("BTF_MEMORY_LIMIT", "10M")
    assert memory.budget() == (10 * memory.MIB, "allowed by the stated limit (BTF_MEMORY_LIMIT)")
    memory.set_limit(5 * memory.MIB)
    try:
        assert memory.budget()[0] == 5 * memory.MIB
        with pytest.raises(memory.MemoryLimitError, match="swatch --size 4096 needs about"):
            memory.require(memory.swatch(4096, ".png"))
        memory.require(memory.Estimate("tiny", 1000))  # under the limit: nothing raised
    finally:
        memory.set_limit(None)


#: The swatch's cap: 1024² PNG is estimated at ~180 MB and completes; 8192² PNG at ~970 MB
#: (it completes under 1.5 GB in about 80 s, too long for CI) is refused under this one.
SWATCH_CAP = 768 * memory.MIB


def test_swatch_fits_under_the_cap_and_8192_is_refused_at_once(tmp_path, lambertian):
    common = ["swatch", lambertian, "--light", "30", "0", "--view", "0", "0"]
    small, _ = run_capped(*common, "--size", "1024", "-o", tmp_path / "s.png", cap=SWATCH_CAP)
    assert small.returncode == 0, small.stderr
    assert (tmp_path / "s.png").stat().st_size > 0
    big, seconds = run_capped(*common, "--size", "8192", "-o", tmp_path / "b.png", cap=SWATCH_CAP)
    assert big.returncode == 2
    assert "swatch --size 8192 needs about" in big.stderr
    assert "address-space limit" in big.stderr
    assert seconds < 20  # refused before evaluating 67 M pixels (that takes over a minute)
    assert not (tmp_path / "b.png").exists()


def test_a_million_virtual_lights_fit_without_an_n_by_width_matrix(tmp_path):
    """2048 × 1024 map, 10⁶ lights: the old column search built a 10⁶ × 2049 matrix (18 GB);
    the per-row search completes under the 1.5 GB cap."""
    rng = np.random.default_rng(5)
    write_exr(tmp_path / "env.exr", rng.random((1024, 2048, 3)).astype(np.float32))
    proc, _ = run_capped("envmap", tmp_path / "env.exr", "--lights", "1000000",
                         "-o", tmp_path / "l.npz")  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    with np.load(tmp_path / "l.npz") as lights:
        assert lights["direction"].shape == (1_000_000, 3)
        assert np.all(np.isfinite(lights["direction"]))
        np.testing.assert_allclose(np.linalg.norm(lights["direction"], axis=1), 1.0, atol=1e-5)


def _huge_header_exr(path) -> None:
    """A valid small EXR whose header claims 16384 × 8192 pixels: the header is all the memory
    model reads, so the refusal must come from it (1.5 GB of pixels are never written)."""
    write_exr(path, np.ones((8, 16, 3), np.float32))
    blob = bytearray(path.read_bytes())
    for name in (b"dataWindow\0box2i\0", b"displayWindow\0box2i\0"):
        at = blob.index(name) + len(name) + 4  # after the attribute's size field
        struct.pack_into("<4i", blob, at, 0, 0, 16383, 8191)
    path.write_bytes(bytes(blob))


def test_a_16k_environment_is_refused_from_its_header(tmp_path):
    _huge_header_exr(tmp_path / "huge.exr")
    proc, seconds = run_capped("envmap", tmp_path / "huge.exr", "-o", tmp_path / "l.npz")
    assert proc.returncode == 2
    # The file named (issue 30 item 16: a refusal that does not say which file).
    assert f"the environment {tmp_path / 'huge.exr'} of 16384×8192 pixels" in proc.stderr
    assert seconds < 20
    assert not (tmp_path / "l.npz").exists()


def test_microgeometry_texels_fit_or_are_refused(tmp_path):
    ok, _ = run_capped("synth", "woven", "--texels", "16", "-o", tmp_path / "w.btfm")
    assert ok.returncode == 0, ok.stderr
    big, seconds = run_capped("synth", "woven", "--texels", "100000", "-o", tmp_path / "x.btfm")
    assert big.returncode == 2 and "woven with 100000 texels" in big.stderr
    assert seconds < 20


def test_render_of_16384_squared_is_refused_before_blender_is_imported():
    """In-process: the refusal comes from the arguments alone; bpy never gets imported."""
    code = (
        "import sys\n"
        "from btf_addon.cli.main import main\n"
        "code = main(['--max-memory', '8G', 'render', '--demo', '-o', '/nonexistent/r.png',"
        " '--resolution', '16384x16384'])\n"
        "print(code, 'bpy' in sys.modules)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=cli_env(), capture_output=True, text=True,
        timeout=60, check=False,
    )  # fmt: skip
    assert proc.stdout.split() == ["2", "False"], proc.stderr
    assert "a 16384x16384 render needs about" in proc.stderr

"""Cache folders that cannot be written (a read-only or odd HOME, as in sandboxes and on
farms): OpenCL still finds its devices and builds kernels, through temporary folders, and the
diagnosis names the folder that failed instead of reporting "no device".

A folder is made unwritable by putting a regular file where it should be (HOME=<a file>):
permission bits would not stop root, which runs CI here."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import cli_env, run_cli

from btf_addon.cl import programs
from btf_addon.core.formats.load import load_btf

pytestmark = pytest.mark.opencl


@pytest.fixture
def blocked_home(tmp_path):
    home = tmp_path / "home-is-a-file"
    home.write_text("not a folder")
    return home


def _env(home, tmp_path):
    # TMPDIR: the fallback folders land in this test's folder, not the machine's /tmp.
    env = cli_env(HOME=str(home), TMPDIR=str(tmp_path / "tmp"))
    for key in ("XDG_CACHE_HOME", "POCL_CACHE_DIR", "BTF_CL_CACHE", "PYOPENCL_CACHE_DIR"):
        env.pop(key, None)
    (tmp_path / "tmp").mkdir()
    return env


def test_eval_on_opencl_works_with_an_unwritable_home_and_names_the_folder(tmp_path, blocked_home):
    run_cli("synth", "lambertian", "-o", tmp_path / "l.btfm")
    q = np.array([[0.5, 0.5, 30, 0, 0, 0]], np.float32)
    np.save(tmp_path / "q.npy", q)
    proc = run_cli(
        "eval", tmp_path / "l.btfm", "--queries", tmp_path / "q.npy",
        "--out", tmp_path / "v.npy", "--backend", "opencl",
        env=_env(blocked_home, tmp_path), check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr and "no device" not in proc.stderr
    assert f"{blocked_home}/.cache" in proc.stderr and "cannot be written" in proc.stderr
    # The device's float32 against the numpy reference: 1e-5 relative covers float32 rounding.
    reference = load_btf(tmp_path / "l.btfm").evaluate_angles(q)
    np.testing.assert_allclose(np.load(tmp_path / "v.npy"), reference, rtol=1e-5)
    assert any((tmp_path / "tmp").iterdir())  # the kernels were cached in the fallback


def test_doctor_names_the_unwritable_cache_folders(tmp_path, blocked_home):
    proc = run_cli("doctor", env=_env(blocked_home, tmp_path), check=False)
    opencl = json.loads(proc.stdout[proc.stdout.index("{") :])["opencl"]
    assert opencl["ok"], opencl
    assert str(blocked_home / ".cache" / "pocl") in opencl["unwritable_cache_folders"]
    assert opencl["kernel_cache"].startswith(str(tmp_path / "tmp"))


def test_set_cache_dir_and_its_fallback(tmp_path, monkeypatch):
    monkeypatch.setattr(programs, "_resolved", {})
    monkeypatch.setattr(programs, "unwritable_folders", {})
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path / "tmp"))  # the fallback's parent
    try:
        programs.set_cache_dir(tmp_path / "ext" / "kernel_cache")
        assert programs.cache_dir() == tmp_path / "ext" / "kernel_cache"
        assert (tmp_path / "ext" / "kernel_cache").is_dir()
        blocker = tmp_path / "file"
        blocker.write_text("x")
        programs.set_cache_dir(blocker / "kernel_cache")
        used = programs.cache_dir()
        assert used.is_relative_to(tmp_path / "tmp")
        assert str(blocker / "kernel_cache") in programs.unwritable_folders
        assert str(blocker / "kernel_cache") in programs.cache_diagnosis()
    finally:
        programs.set_cache_dir(None)

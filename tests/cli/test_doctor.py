"""``doctor`` reports cleanly whatever is missing."""

from __future__ import annotations

import json
import subprocess
import sys

from helpers import ROOT, cli_env


def doctor(env_overrides: dict) -> dict:
    env = cli_env(**env_overrides)
    proc = subprocess.run(
        [sys.executable, "-m", "btf_addon", "doctor"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_doctor_reports_this_machine():
    report = doctor({})
    assert report["blender"]["ok"] and report["blender"]["version"].startswith("5.0")
    assert report["opencl"]["ok"] and report["opencl"]["devices"]
    assert report["opengl"]["ok"] and report["opengl"]["renderer"]
    assert report["hidraw"]["ok"]
    assert set(report["summary"]) >= {"blender", "opencl", "opengl", "hidraw", "openxr"}
    if not report["openxr"]["ok"]:  # no headset runtime here: reported with a hint, not a crash
        assert "pyopenxr" in report["openxr"]["how_to_fix"]


def test_doctor_with_opencl_hidden(tmp_path):
    """OCL_ICD_VENDORS pointed at a folder with no vendor files hides every OpenCL driver. (The
    ICD loader in pyopencl's wheel falls back to its built-in vendor list when the folder exists
    but is empty, so the path given is one that does not exist.)"""
    report = doctor({"OCL_ICD_VENDORS": str(tmp_path / "no-vendors"), "OCL_ICD_FILENAMES": ""})
    assert report["opencl"]["ok"] is False
    assert "no OpenCL platform" in report["opencl"]["error"]
    assert "pocl" in report["opencl"]["how_to_fix"]
    assert report["blender"]["ok"]  # the rest still reported


def test_doctor_with_no_display_libraries(tmp_path):
    """A broken EGL (no vendor) is reported, not fatal."""
    report = doctor(
        {
            "__EGL_VENDOR_LIBRARY_FILENAMES": str(tmp_path / "none.json"),
            "EGL_PLATFORM": "surfaceless",
        }
    )
    assert "opengl" in report
    if not report["opengl"]["ok"]:
        assert "how_to_fix" in report["opengl"]

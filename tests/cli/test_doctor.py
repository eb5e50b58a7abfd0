"""``doctor``: the report's shape, failures reported as data, and its exit code — whatever this
machine happens to have.

Probe outcomes are made certain by a folder, first on PYTHONPATH, of modules that shadow real
ones: a ``bpy`` that kills its own process with SIGSEGV (as broken GPU drivers do), an
``OpenEXR`` that raises on import, and an ``xr`` (pyopenxr) that imports fine. OpenCL drivers
are hidden through the ICD loader's own variable. The other probes report what this machine has,
and only the report's rules are checked for them.
"""

from __future__ import annotations

import json
import os
import platform
import signal
import subprocess
import sys

import pytest
from helpers import ROOT, cli_env

import btf_addon
from btf_addon.cli.doctor import read_probe_output
from btf_addon.diagnostics.probes import PROBES, RESULT_MARKER

SHADOWS = {
    "bpy.py": "import os, signal\nos.kill(os.getpid(), signal.SIGSEGV)\n",
    "OpenEXR.py": "raise ImportError('a broken OpenEXR build (test shadow)')\n",
    "xr.py": "__version__ = '0.0-shadow'\n",
}


def run_doctor(*args: str, env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "btf_addon", "doctor", *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )


@pytest.fixture(scope="module")
def shadowed(tmp_path_factory) -> subprocess.CompletedProcess:
    folder = tmp_path_factory.mktemp("shadow")
    for name, text in SHADOWS.items():
        (folder / name).write_text(text)
    # OCL_ICD_VENDORS pointed at a folder that does not exist hides every OpenCL driver (the
    # ICD loader in pyopencl's wheel falls back to its built-in list for an empty folder).
    env = cli_env(
        PYTHONPATH=os.pathsep.join([str(folder), str(ROOT)]),
        OCL_ICD_VENDORS=str(folder / "no-vendors"),
        OCL_ICD_FILENAMES="",
    )
    return run_doctor(env=env)


@pytest.fixture(scope="module")
def report(shadowed) -> dict:
    assert shadowed.returncode == 0, shadowed.stderr
    return json.loads(shadowed.stdout)


def test_missing_parts_still_exit_0_with_the_report_on_stdout(shadowed, report):
    assert shadowed.returncode == 0
    assert not all(report["summary"].values())  # at least the shadowed probes failed


def test_report_structure(report):
    assert list(report) == ["btf_materials", "python", "platform", *PROBES, "summary"]
    assert report["btf_materials"] == btf_addon.__version__
    assert report["python"] == platform.python_version()  # the doctor runs this interpreter
    assert list(report["summary"]) == list(PROBES)
    for name, probe in PROBES.items():
        result = report[name]
        assert isinstance(result["ok"], bool), name
        assert report["summary"][name] is result["ok"], name
        if result["ok"]:
            assert "error" not in result and "how_to_fix" not in result, name
        else:
            assert isinstance(result["error"], str) and result["error"], name
            assert result["how_to_fix"] == probe.hint, name


def test_a_probe_that_crashes_its_process_is_reported_missing(report):
    blender = report["blender"]
    assert blender["ok"] is False
    assert blender["error"].startswith(
        f"probe process failed (killed by signal {int(signal.SIGSEGV)})"
    )
    assert blender["how_to_fix"] == PROBES["blender"].hint
    assert "bpy==" in blender["how_to_fix"]


def test_a_probe_that_raises_is_reported_with_its_exception(report):
    assert report["openexr"] == {
        "ok": False,
        "error": "ImportError: a broken OpenEXR build (test shadow)",
        "how_to_fix": PROBES["openexr"].hint,
    }


def test_hidden_opencl_drivers_are_reported_missing(report):
    opencl = report["opencl"]
    assert opencl["ok"] is False
    assert opencl["error"].startswith("OpenCLUnavailableError: no OpenCL platform found")
    assert "pocl" in opencl["how_to_fix"]


def test_only_the_bundled_driver_visible_reports_whether_it_builds(tmp_path):
    """An empty OCL_ICD_VENDORS folder leaves only the PoCL bundled with pyopencl: the report
    names it as bundled with its driver version and says whether it builds. Where it cannot
    (a CPU newer than its LLVM 14) the probe fails with the compiler's reason and the device
    list is still there; where it can, F12 uses it."""
    empty = tmp_path / "vendors"
    empty.mkdir()
    proc = subprocess.run(
        [sys.executable, "-c", "from btf_addon.diagnostics.probes import run_probe; "
         "run_probe('opencl')"],
        cwd=ROOT, env=cli_env(OCL_ICD_VENDORS=str(empty), OCL_ICD_FILENAMES=""),
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    result = read_probe_output(proc)
    devices = result["devices"]
    assert len(devices) == 1 and devices[0]["bundled"], result
    bundled = devices[0]
    assert bundled["label"].endswith(", bundled)") and "PoCL 3.0" in bundled["label"]
    if bundled["builds"]:
        assert result["ok"] and result["f12_device"] == bundled["label"] and bundled["used"]
    else:
        assert not result["ok"] and result["f12_device"] is None and not bundled["used"]
        assert bundled["reason"] in result["error"] and "pocl-opencl-icd" in result["error"]


def test_a_probe_that_succeeds_reports_its_facts(report):
    assert report["openxr"]["ok"] is True
    assert report["openxr"]["pyopenxr"] == "0.0-shadow"
    assert report["summary"]["openxr"] is True


def test_unknown_arguments_exit_2():
    proc = run_doctor("--no-such-option", env=cli_env())
    assert proc.returncode == 2
    assert "unrecognized arguments: --no-such-option" in proc.stderr
    assert proc.stdout == ""  # no probe ran, no report printed


@pytest.mark.parametrize(
    ("stdout", "returncode", "expected"),
    [
        # A driver's chatter on stdout before the marker is not mistaken for the result.
        (f'driver says {{"ok": false}}\n{RESULT_MARKER}{{"ok": true, "n": 1}}\n', 0, {"n": 1}),
        (f"{RESULT_MARKER}not json\n", 0, {"error": "unreadable probe result 'not json'"}),
        (f'{RESULT_MARKER}{{"n": 1}}\n', 0, {"error": "malformed probe result '{\"n\": 1}'"}),
        ("", 3, {"error": "probe process failed (exit code 3) last words"}),
    ],
)
def test_reading_a_probe_process_output(stdout, returncode, expected):
    proc = subprocess.CompletedProcess([], returncode, stdout, "first\nlast words\n")
    result = read_probe_output(proc)
    assert result == {"ok": "error" not in expected, **expected}

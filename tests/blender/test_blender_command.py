"""``blender --command btf …``: the CLI for someone who installed only the zip.

The Blender binary is not installable here (only the bpy module is), so the check does what
``--command`` does: in a fresh Blender (bpy in a subprocess) with the zip installed and
enabled, the function registered with ``bpy.utils.register_cli_command`` is called with an
argv. Its exit codes and its own output must equal ``python -m btf_addon`` with the same
arguments (this checkout, another process), except the program name in usage lines; disabling
the add-on must unregister the command."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tempfile

import pytest
from helpers import cli_env, read_png, run_cli

SCRIPT = r"""
import contextlib, importlib, io, json, sys
import bpy

zip_path, jobs_path, out = sys.argv[-3:]
assert bpy.ops.extensions.package_install_files(
    filepath=zip_path, repo="user_default", enable_on_install=True
) == {"FINISHED"}
command = importlib.import_module("bl_ext.user_default.btf_materials.btf_addon.cli.blender_command")
handle = command._handle
results = {"registered": handle is not None, "runs": []}
for argv in json.load(open(jobs_path)):
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = command.execute(argv)  # what `blender --command btf ARGV` calls
    results["runs"].append({"code": code, "stdout": stdout.getvalue(), "stderr": stderr.getvalue()})
bpy.ops.preferences.addon_disable(module="bl_ext.user_default.btf_materials")
results["handle_after_disable"] = command._handle is not None
try:
    bpy.utils.unregister_cli_command(handle)  # gone already: Blender refuses a second time
    results["still_registered"] = True
except Exception:
    results["still_registered"] = False
json.dump(results, open(out, "w"))
"""


def _normalise(text: str) -> str:
    """The program name (and how argparse wraps usage lines around it) and measured times are
    the only differences allowed."""
    text = text.replace("blender --command btf", "python -m btf_addon")
    text = re.sub(r"in \d+(\.\d+)? s\b", "in T s", text)
    return "\n".join(" ".join(line.split()) for line in text.splitlines() if line.strip())


@pytest.fixture(scope="module")
def both(extension_zip, tmp_path_factory):
    folder = tmp_path_factory.mktemp("blender-command")
    btfm = folder / "woven.btfm"
    jobs = [
        ["synth", "woven", "-o", str(btfm)],
        ["info", str(btfm)],
        ["info", str(folder / "missing.btfm")],  # input error: exit 2
        ["frobnicate"],  # usage error: exit 2
        ["render", "--demo", "-o", str(folder / "{side}.png"), "--resolution", "32x18",
         "--lights", "4"],
        ["doctor"],
    ]  # fmt: skip
    blender_jobs = [[a.replace("{side}", "blender") for a in job] for job in jobs]
    (folder / "jobs.json").write_text(json.dumps(blender_jobs))
    user = tempfile.mkdtemp(prefix="btf-blender-user-", dir=folder)
    out = folder / "results.json"
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(extension_zip), str(folder / "jobs.json"), str(out)],
        env=cli_env(BLENDER_USER_RESOURCES=user),
        capture_output=True,
        text=True,
        timeout=900,
        check=False,
    )
    assert proc.returncode == 0 and out.exists(), proc.stdout[-3000:] + proc.stderr[-3000:]
    blender = json.loads(out.read_text())
    btfm.unlink()  # the Python side writes it again
    python = []
    for job in jobs:
        done = run_cli(*[a.replace("{side}", "python") for a in job], check=False)
        python.append({"code": done.returncode, "stdout": done.stdout, "stderr": done.stderr})
    return folder, jobs, blender, python


def test_registered_while_enabled_and_gone_when_disabled(both):
    _folder, _jobs, blender, _python = both
    assert blender["registered"]
    assert not blender["handle_after_disable"] and not blender["still_registered"]


def test_same_exit_codes_as_python_m(both):
    _folder, jobs, blender, python = both
    codes = [run["code"] for run in blender["runs"]]
    assert codes == [run["code"] for run in python], list(zip(jobs, codes, strict=True))
    assert codes == [0, 0, 2, 2, 0, 0]


def test_same_messages_as_python_m(both):
    _folder, jobs, blender, python = both
    for job, b, p in zip(jobs[:4], blender["runs"][:4], python[:4], strict=True):
        assert _normalise(b["stdout"]) == _normalise(p["stdout"]), job
        assert _normalise(b["stderr"]) == _normalise(p["stderr"]), job
    assert "usage: python -m btf_addon" in _normalise(blender["runs"][3]["stderr"])
    assert "blender --command btf" in blender["runs"][3]["stderr"]  # its own name in usage
    # render: the CLI's own summary line (Blender's "Saved:" lines are its C code's, on fd 1)
    rendered = [
        _normalise(run["stdout"]).strip().splitlines()[-1]
        for run in (blender["runs"][4], python[4])
    ]
    assert rendered[0].replace("blender.png", "X.png") == rendered[1].replace("python.png", "X.png")


def test_same_render_and_doctor_verdicts(both):
    folder, _jobs, blender, python = both
    import numpy as np

    a = read_png(folder / "blender.png")
    b = read_png(folder / "python.png")
    assert a.shape == b.shape == (18, 32, 4)
    assert np.array_equal(a, b)  # same code, same device, same lights: the same pixels
    doctor_b = json.loads(blender["runs"][5]["stdout"])
    doctor_p = json.loads(python[5]["stdout"])
    assert doctor_b["summary"] == doctor_p["summary"]
    if doctor_p["opencl"]["ok"]:
        assert doctor_b["opencl"]["f12_device"] == doctor_p["opencl"]["f12_device"]

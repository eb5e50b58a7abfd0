"""Ctrl-C at the moments of a Blender-based command that used to go wrong (issue 30 items 3
and 15): during ``import bpy`` (Blender's start-up: a half-registered Blender segfaulted, exit
139), inside the render engine's callback (Blender printed the KeyboardInterrupt's traceback
before the command exited 130) and after the command's work, while the process exits (an
uncaught KeyboardInterrupt ended it by SIGINT, exit -2, hiding its status).

Each run is ``python -m btf_addon render --demo`` as a user starts it (``runpy`` runs the
package's ``__main__``), with a hook that sends the process its own SIGINT at that moment, so
the moment is exact rather than a timing guess."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap

import pytest
from helpers import ROOT, cli_env

pytest.importorskip("bpy", reason="Blender as a Python module (pip install bpy==5.0.1)")

RUN_MAIN = """
sys.argv[0] = "btf_addon"
runpy.run_module("btf_addon", run_name="__main__", alter_sys=True)
"""

#: SIGINT when Blender's start-up imports ``module`` (one of its own UI or operator packages,
#: imported while ``import bpy`` registers Blender's classes).
DURING_IMPORT = """
import importlib.abc, os, runpy, signal, sys
class Interrupt(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name == {module!r}:
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None
sys.meta_path.insert(0, Interrupt())
"""

#: SIGINT once the command returned its status, as the process begins to exit.
AFTER_THE_WORK = """
import os, runpy, signal, sys, time
from btf_addon.blender import compat
exit_python = compat.exit_python
def late(code):
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.2)  # the signal is handled (or ignored) here
    exit_python(code)
compat.exit_python = late
"""

#: A render callback that says so and blocks: the signal lands inside Blender's callback.
IN_THE_RENDER = """
import runpy, sys, time
from btf_addon.blender import final_render
def slow(engine, depsgraph):
    print("rendering", flush=True)
    time.sleep(120)
final_render.render = slow
"""


def _render(script: str, out, wait_for: str | None = None) -> subprocess.CompletedProcess:
    args = [sys.executable, "-c", textwrap.dedent(script) + RUN_MAIN, "render", "--demo"]
    args += ["-o", str(out), "--resolution", "32x24"]
    proc = subprocess.Popen(
        args, cwd=ROOT, env=cli_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        if wait_for is not None:
            while (line := proc.stdout.readline()) and line.strip() != wait_for:
                pass
            assert line.strip() == wait_for
            proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        proc.kill()
    return subprocess.CompletedProcess(args, proc.returncode, stdout, stderr)


@pytest.mark.parametrize("module", ["bl_ui", "bl_operators"])
def test_ctrl_c_during_blenders_start_up_exits_130(tmp_path, module):
    # Before: exit 139 (segfault) after Blender's half-done start-up, 2 of 2 modules.
    out = tmp_path / "r.png"
    proc = _render(DURING_IMPORT.format(module=module), out)
    assert proc.returncode == 130, proc.stderr[-3000:]
    assert proc.stderr.strip().splitlines()[-1].startswith("interrupted:")
    assert "Traceback" not in proc.stderr
    assert not out.exists()


def test_ctrl_c_inside_the_render_callback_prints_no_traceback(tmp_path):
    out = tmp_path / "r.png"
    proc = _render(IN_THE_RENDER, out, wait_for="rendering")
    assert proc.returncode == 130, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr and "KeyboardInterrupt" not in proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("interrupted:")
    assert not out.exists()


def test_ctrl_c_after_the_work_keeps_the_commands_status(tmp_path):
    # Before: exit -2 (killed by SIGINT) although the image was written.
    out = tmp_path / "r.png"
    proc = _render(AFTER_THE_WORK, out)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert out.is_file()
    assert "Traceback" not in proc.stderr

"""``doctor``: a JSON report of what this machine offers the add-on. Never crashes.

The report: ``btf_materials`` (version), ``python``, ``platform``, then one object per probe
(``diagnostics.probes.PROBES``, in that order) — ``{"ok": true, ...facts}`` or ``{"ok": false,
"error": ..., "how_to_fix": ...}`` — and ``summary`` (probe name → ok). The exit code is 0
whenever the report was printed: a missing part is a fact to report, not a failure of the
doctor.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

from .. import __version__
from ..diagnostics.probes import PROBES, RESULT_MARKER

PROBE_TIMEOUT_S = 180


def _probe_in_subprocess(name: str) -> dict:
    """Run one probe in a fresh interpreter (a crashing driver takes only that process down).
    It imports ``btf_addon`` as a top-level package from the folder that holds this copy, with
    this process's package folders (inside Blender: the extension's own site-packages, where
    its bundled pyopencl lives; Blender's ``bl_ext.…`` package names exist only inside
    Blender). Only site-packages folders: Blender's scripts/modules holds a ``bpy`` package
    that would shadow the bpy module in a plain interpreter."""
    package_parent = str(Path(__file__).resolve().parents[2])
    packages = [p for p in sys.path if Path(p).name in ("site-packages", "dist-packages")]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        filter(None, [package_parent, env.get("PYTHONPATH"), *packages])
    )
    code = f"from btf_addon.diagnostics.probes import run_probe; run_probe({name!r})"
    try:
        proc = subprocess.run(
            [sys.executable, "-c", code],
            capture_output=True,
            text=True,
            timeout=PROBE_TIMEOUT_S,
            env=env,
            check=False,
        )
    except subprocess.TimeoutExpired:
        return {"ok": False, "error": f"probe did not finish within {PROBE_TIMEOUT_S} s"}
    except OSError as exc:
        return {"ok": False, "error": f"could not start a probe process ({exc})"}
    return read_probe_output(proc)


def read_probe_output(proc: subprocess.CompletedProcess) -> dict:
    """A finished probe process → its result dict, or a failure saying why there is none."""
    marker = proc.stdout.rfind(RESULT_MARKER)
    if marker < 0:
        reason = (
            f"killed by signal {-proc.returncode}"
            if proc.returncode < 0
            else f"exit code {proc.returncode}"
        )
        tail = (proc.stderr.strip().splitlines() or [""])[-1]
        return {"ok": False, "error": f"probe process failed ({reason}) {tail}".strip()}
    line = (proc.stdout[marker + len(RESULT_MARKER) :].splitlines() or [""])[0]
    try:
        result = json.loads(line)
    except ValueError:
        return {"ok": False, "error": f"unreadable probe result {line[:200]!r}"}
    if not isinstance(result, dict) or not isinstance(result.get("ok"), bool):
        return {"ok": False, "error": f"malformed probe result {line[:200]!r}"}
    return result


def report() -> dict:
    out: dict = {
        "btf_materials": __version__,
        "python": platform.python_version(),
        "platform": f"{platform.system()} {platform.machine()}",
    }
    for probe in PROBES.values():
        result = _probe_in_subprocess(probe.name)
        if not result["ok"]:
            result["how_to_fix"] = probe.hint
        out[probe.name] = result
    out["summary"] = {name: out[name]["ok"] for name in PROBES}
    return out


def main(args) -> int:
    print(json.dumps(report(), indent=2))
    return 0

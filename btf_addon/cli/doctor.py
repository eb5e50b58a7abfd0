"""``doctor``: a JSON report of what this machine offers the add-on. Never crashes."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

from .. import __version__
from ..diagnostics.probes import PROBES

PROBE_TIMEOUT_S = 180


def _probe_in_subprocess(name: str) -> dict:
    package_parent = str(Path(__file__).resolve().parents[2])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [package_parent, env.get("PYTHONPATH")]))
    package = __package__.rsplit(".", 1)[0]
    code = f"from {package}.diagnostics.probes import run_probe; run_probe({name!r})"
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
    marker = proc.stdout.rfind("@@PROBE@@")
    if marker < 0:
        reason = (
            f"killed by signal {-proc.returncode}"
            if proc.returncode < 0
            else f"exit code {proc.returncode}"
        )
        tail = (proc.stderr.strip().splitlines() or [""])[-1]
        return {"ok": False, "error": f"probe process failed ({reason}) {tail}".strip()}
    return json.loads(proc.stdout[marker + len("@@PROBE@@") :].splitlines()[0])


def report() -> dict:
    out: dict = {
        "btf_materials": __version__,
        "python": platform.python_version(),
        "platform": f"{platform.system()} {platform.machine()}",
    }
    for name, (_func, hint) in PROBES.items():
        result = _probe_in_subprocess(name)
        if not result.get("ok"):
            result["how_to_fix"] = hint
        out[name] = result
    out["summary"] = {name: bool(out[name].get("ok")) for name in PROBES}
    return out


def main(args) -> int:
    print(json.dumps(report(), indent=2))
    return 0

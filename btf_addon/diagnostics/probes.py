"""One function per optional part of the system; each returns a JSON-able dict or raises.

The doctor runs each probe in its own subprocess (``run_probe``), so a driver that crashes the
process (it happens with broken GPU stacks) is reported instead of taking the doctor down.
"""

from __future__ import annotations

import importlib.util
import json
import platform
import sys
from collections.abc import Callable
from dataclasses import dataclass


class ProbeFailedError(RuntimeError):
    """A failed check that still found facts worth reporting (the OpenCL devices that exist
    when none of them can build): ``run_probe`` puts them beside the error."""

    def __init__(self, message: str, facts: dict):
        super().__init__(message)
        self.facts = facts


def probe_blender() -> dict:
    if importlib.util.find_spec("bpy") is None:
        raise RuntimeError("the bpy module is not installed")
    import bpy

    return {
        "version": bpy.app.version_string,
        "background": bool(bpy.app.background),
        "python": platform.python_version(),
    }


def probe_opencl() -> dict:
    """Every device with its driver, whether it builds the probe program (and why not), and
    which one F12 uses. Fails (with each device's reason) when none can build."""
    from ..cl import programs
    from ..cl.context import install_advice
    from ..cl.devices import device_report

    devices = device_report()  # first: it moves unwritable driver caches to temporary folders
    kernel_cache = str(programs.cache_dir())
    if not devices:
        raise RuntimeError(
            f"OpenCL platforms exist but offer no devices{programs.cache_diagnosis()}"
        )
    used = [d for d in devices if d["used"]]
    facts = {
        "devices": devices,
        "default_device": used[0]["index"] if used else None,
        "f12_device": used[0]["label"] if used else None,
        "kernel_cache": kernel_cache,
        # Folder → why it could not be written; a temporary folder was used instead.
        "unwritable_cache_folders": dict(programs.unwritable_folders),
    }
    if not used:
        reasons = "; ".join(f"{d['label']}: {d['reason']}" for d in devices)
        raise ProbeFailedError(
            f"no OpenCL device can build programs ({reasons}); F12 draws through the GLSL path. "
            f"{install_advice()}",
            facts,
        )
    return facts


def probe_opengl() -> dict:
    from ..gl.context import probe_egl

    return probe_egl()


def probe_hidraw() -> dict:
    # The module the Wiimote transport uses (controllers/hid_transport.py's rule, repeated: a
    # sibling layer): Linux's `hidraw` backend sees Bluetooth HID, its libusb `hid` does not;
    # elsewhere `hid` is the native backend, which does.
    name = "hidraw" if sys.platform.startswith("linux") else "hid"
    module = importlib.import_module(name)
    version = getattr(module, "__version__", None) or _dist_version("hidapi")
    return {"module": name, "hidapi_version": version}


def probe_openxr() -> dict:
    import ctypes.util

    found = {}
    if importlib.util.find_spec("xr") is not None:
        import xr

        found["pyopenxr"] = getattr(xr, "__version__", "installed")
    loader = ctypes.util.find_library("openxr_loader")
    if loader:
        found["loader"] = loader
    if not found:
        raise RuntimeError("neither the pyopenxr package nor an OpenXR loader library was found")
    return found


def probe_openexr() -> dict:
    import OpenEXR

    return {"version": getattr(OpenEXR, "__version__", _dist_version("openexr"))}


def _dist_version(name: str) -> str | None:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(name)
    except PackageNotFoundError:
        return None


@dataclass(frozen=True)
class Probe:
    name: str
    check: Callable[[], dict]  # → JSON-able facts about what was found; raises when missing
    hint: str  # how to install what is missing, shown with a failed check


PROBES: dict[str, Probe] = {
    probe.name: probe
    for probe in (
        Probe(
            "blender",
            probe_blender,
            "Install Blender as a Python module: pip install bpy==5.0.1 (Python 3.11), "
            "or run inside Blender 4.2+.",
        ),
        Probe(
            "opencl",
            probe_opencl,
            "Install a GPU vendor's OpenCL driver, or a CPU driver: Debian/Ubuntu "
            "apt-get install pocl-opencl-icd, else pip install pocl-binary-distribution (LLVM 14: "
            "not for CPUs newer than it knows); final renders need OpenCL.",
        ),
        Probe(
            "opengl",
            probe_opengl,
            "Install Mesa's EGL and DRI drivers (Debian: apt-get install libegl1 libegl-mesa0 "
            "libgl1-mesa-dri) for the headless GLSL renderer.",
        ),
        Probe(
            "hidraw",
            probe_hidraw,
            "Install hidapi (pip install hidapi; the extension bundles it) for Wiimote "
            "support; the add-on works without a controller.",
        ),
        Probe(
            "openxr",
            probe_openxr,
            "Optional: install an OpenXR runtime and pip install pyopenxr to drive headsets "
            "outside Blender's own VR session.",
        ),
        Probe(
            "openexr",
            probe_openexr,
            "Install OpenEXR (pip install openexr) to read and write EXR files.",
        ),
    )
}

#: Precedes the one JSON line a probe process prints, so that anything a driver prints on
#: stdout before it cannot be mistaken for the result.
RESULT_MARKER = "@@PROBE@@"


def run_probe(name: str) -> None:
    """Subprocess entry: print the probe's JSON result after ``RESULT_MARKER`` on stdout:
    ``{"ok": true, **facts}`` or ``{"ok": false, "error": "<exception type>: <message>"}``."""
    try:
        line = json.dumps({"ok": True, **PROBES[name].check()})
    except Exception as exc:  # report any failure as data: the doctor must never crash
        facts = exc.facts if isinstance(exc, ProbeFailedError) else {}
        line = json.dumps({"ok": False, "error": f"{type(exc).__name__}: {exc}", **facts})
    sys.stdout.write("\n" + RESULT_MARKER + line + "\n")

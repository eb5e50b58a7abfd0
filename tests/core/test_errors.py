"""One root for the add-on's errors (core/errors.py): every exception class the bpy-free code
defines derives from ``BTFMaterialsError`` and carries the CLI's exit status, so callers catch
one type and the CLI has one boundary (cli/main.py). The few exceptions that never leave
their module (parsing steps that are turned into a root error before they reach a caller) are
listed with the reason."""

from __future__ import annotations

import importlib
import inspect

from helpers import ROOT

from btf_addon.core.errors import BTFError, BTFMaterialsError, BuildError, DeviceError

#: Internal signals, caught where they are raised, never shown to a caller.
INTERNAL = {
    # A malformed Wiimote report: the driver logs and skips it (controllers/wiimote/driver.py).
    "btf_addon.controllers.wiimote.reports.ReportError",
    # A diagnostics probe's failure with facts: run_probe turns it into the doctor's JSON.
    "btf_addon.diagnostics.probes.ProbeFailedError",
    # SIGTERM as a KeyboardInterrupt: an interrupt, not an error (exit 130 at the boundary).
    "btf_addon.cli.main.Terminated",
}


def _bpy_free_modules():
    for path in sorted((ROOT / "btf_addon").rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if "blender" in parts or parts[-1] == "__main__":
            continue
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        yield importlib.import_module(name)


def test_every_error_class_has_the_one_root():
    outside = []
    for module in _bpy_free_modules():
        for name, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ != module.__name__ or not issubclass(cls, BaseException):
                continue
            qualified = f"{module.__name__}.{name}"
            if not issubclass(cls, BTFMaterialsError) and qualified not in INTERNAL:
                outside.append(qualified)
    assert outside == []


def test_exit_codes_and_kinds():
    from btf_addon.cl.devices import OpenCLUnavailableError
    from btf_addon.cl.programs import OpenCLCompileError
    from btf_addon.gl.interface import ShaderCompileError
    from btf_addon.xr.egl import EGLError
    from btf_addon.xr.errors import BridgeError, NoRuntimeError

    assert BTFError("x").exit_code == DeviceError("x").exit_code == 2
    assert issubclass(OpenCLUnavailableError, DeviceError) and issubclass(EGLError, DeviceError)
    assert issubclass(OpenCLCompileError, BuildError) and issubclass(ShaderCompileError, BuildError)
    assert BuildError("x").exit_code == BridgeError("x").exit_code == 1
    assert NoRuntimeError("x").exit_code == 3
    # Driver failures stay RuntimeErrors for code that has always caught them so.
    assert issubclass(DeviceError, RuntimeError) and issubclass(BuildError, RuntimeError)

"""The zips carry only what runs: sizes within the budget a download should have, and the
pyopenxr that Blender installs from them still loads its OpenXR loader (tools/slim_wheels.py).

Budgets (issue "A fresh machine renders"): Linux ≤ 80 MB (it bundles PoCL, ~58 MB of it),
Windows and macOS ≤ 45 MB. The published pyopenxr wheel alone was 57 MB in every zip."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile

import pytest

BUDGET_MB = {"linux_x64": 80, "windows_x64": 45, "macos_arm64": 45}


def test_each_platform_zip_within_its_budget(extension_zip):
    for platform, budget in BUDGET_MB.items():
        path = extension_zip.with_name(extension_zip.name.replace("linux_x64", platform))
        assert path.is_file(), path
        size_mb = path.stat().st_size / 1e6
        assert size_mb <= budget, f"{path.name}: {size_mb:.1f} MB > {budget} MB"


def _pyopenxr_files(zip_path) -> list[str]:
    with zipfile.ZipFile(zip_path) as z:
        wheels = [n for n in z.namelist() if n.split("/")[-1].startswith("pyopenxr-")]
        assert len(wheels) == 1, wheels  # exactly this platform's derived wheel
        with z.open(wheels[0]) as fh, zipfile.ZipFile(fh) as wheel:
            return wheel.namelist()


@pytest.mark.parametrize(
    "platform, loader",
    [
        ("linux_x64", "linux_x86_64/libopenxr_loader.so linux_x86_64/libXrApiLayer_python.so"),
        ("windows_x64", "windows_x86_64/openxr_loader.dll windows_x86_64/XrApiLayer_python.dll"),
        ("macos_arm64", ""),  # pyopenxr has no macOS loader: modules only, as published
    ],
)
def test_pyopenxr_keeps_its_platform_loader_and_no_api_layer(extension_zip, platform, loader):
    """The loader and the Python-layer dispatch library ``import xr`` loads; no API layer."""
    names = _pyopenxr_files(
        extension_zip.with_name(extension_zip.name.replace("linux_x64", platform))
    )
    native = sorted(n.split("/", 2)[2] for n in names if n.endswith((".so", ".dll", ".dylib")))
    assert native == sorted(loader.split()), native
    assert "xr/__init__.py" in names and "xr/api_layer/__init__.py" in names


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the Linux wheel's loader")
def test_slim_pyopenxr_imports_and_loads_its_loader(extension_zip, tmp_path):
    """Installed alone (pip, as Blender extracts wheels), ``import xr`` works and its OpenXR
    loader answers a real call: the API layers it lost were never needed. (The bridge's own
    tests drive the installed zip's pyopenxr against the test runtime, tests/xr_runtime.)"""
    with zipfile.ZipFile(extension_zip) as z:
        name = next(n for n in z.namelist() if n.split("/")[-1].startswith("pyopenxr-"))
        wheel = tmp_path / name.split("/")[-1]
        wheel.write_bytes(z.read(name))
    target = tmp_path / "site"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--no-index",
            "--target",
            str(target),
            str(wheel),
        ],
        check=True,
    )
    code = (
        "import sys; sys.path.insert(0, sys.argv[1]); import xr; "
        "assert xr.__file__.startswith(sys.argv[1]), xr.__file__; "
        "print(len(xr.enumerate_api_layer_properties()))"
    )
    # Without the layer folders an earlier `import xr` in this process put in its environment.
    env = {k: v for k, v in os.environ.items() if not k.startswith("XR_")}
    proc = subprocess.run(
        [sys.executable, "-c", code, str(target)],
        capture_output=True,
        text=True,
        check=False,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    # The loader answers (no runtime is needed for this call) and finds no layer: the cut
    # wheel offers none, and XR_API_LAYER_PATH points at its folder alone.
    assert proc.stdout.strip() == "0", proc.stdout

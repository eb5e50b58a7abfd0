"""Fixtures for the OpenXR tests: the BTF test runtime (tests/xr_runtime), built once per session
with the system C compiler and loaded by the REAL OpenXR loader (pyopenxr's) via XR_RUNTIME_JSON.

The whole directory skips (saying why) only when the compiler or headers are missing; a compile
error fails loudly.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from xr_runtime.build import RuntimeBuildError, build_runtime, missing_tools
from xr_runtime.readback import Frame, read_capture


def pytest_collection_modifyitems(config, items):
    missing = missing_tools()
    if not missing:
        return
    here = Path(__file__).resolve().parent
    skip = pytest.mark.skip(reason="no OpenXR test runtime: missing " + "; ".join(missing))
    for item in items:
        if here in Path(str(item.fspath)).resolve().parents:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def xr_runtime_manifest(tmp_path_factory) -> Path:
    """The test runtime's loader manifest (the .so beside it), built once per session."""
    try:
        return build_runtime(tmp_path_factory.mktemp("xr_runtime"))
    except RuntimeBuildError as exc:
        if missing_tools():
            pytest.skip(str(exc))
        raise


class TestRuntime:
    """Controls the test runtime for one test: ``script(**overrides)`` writes the control JSON and
    points XR_RUNTIME_JSON / BTF_XR_TEST_SCRIPT at it; ``captured()`` reads the submitted frames.
    """

    __test__ = False  # a fixture's object, not a test class

    def __init__(self, manifest: Path, tmp_path: Path, monkeypatch):
        self.manifest = manifest
        self.dir = tmp_path / "xr_runtime"
        self.dir.mkdir(exist_ok=True)
        self.capture_dir = self.dir / "capture"
        self._monkeypatch = monkeypatch

    def script(self, **overrides) -> Path:
        """Write the control script (every key optional; see docs/development.md) and select
        this runtime. ``capture_dir`` defaults to a fresh folder of this test."""
        data = {"capture_dir": str(self.capture_dir), **overrides}
        if data.get("capture_dir") is not None:
            self.capture_dir = Path(data["capture_dir"])
        path = self.dir / "script.json"
        path.write_text(json.dumps(data, indent=1))
        self._monkeypatch.setenv("XR_RUNTIME_JSON", str(self.manifest))
        self._monkeypatch.setenv("BTF_XR_TEST_SCRIPT", str(path))
        return path

    def captured(self) -> list[Frame]:
        """The frames submitted so far, images LINEAR float32 (h, w, 4), row 0 at the bottom."""
        return read_capture(self.capture_dir) if self.capture_dir.is_dir() else []


@pytest.fixture
def xr_runtime(xr_runtime_manifest, tmp_path, monkeypatch) -> TestRuntime:
    """The test runtime, selected for this test with the default script."""
    runtime = TestRuntime(xr_runtime_manifest, tmp_path, monkeypatch)
    runtime.script()
    return runtime

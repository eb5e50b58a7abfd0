"""Helpers shared by the tests: data locations, skips that state their reason, sampling."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
SHARED_BTFBASE = ROOT.parent / "shared" / "data" / "btfbase"
MATERIALS = ("alu", "wallpaper")


def shared_material(name: str) -> Path:
    path = SHARED_BTFBASE / name
    if not (path / "all_materialInfo.txt").is_file():
        pytest.skip(
            f"real BTFbase data not found at {path}: it ships in ../shared beside CI's "
            "clone, not in a user's clone"
        )
    return path


def studiolights_dir() -> Path:
    """Blender's bundled HDR environments, found without importing bpy."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        pytest.skip("the bpy module (which ships the studiolight EXRs) is not installed")
    bpy_dir = Path(next(iter(spec.submodule_search_locations)))
    found = sorted(bpy_dir.glob("*/datafiles/studiolights/world"))
    if not found:
        pytest.skip(f"no studiolights inside {bpy_dir}")
    return found[-1]


def random_hemisphere(rng: np.random.Generator, n: int) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def cli_env(**overrides: str) -> dict[str, str]:
    """Environment for a CLI subprocess: this checkout importable from any folder, and not the
    isolated Blender user folder that tests/blender sets for this process (a subprocess would
    otherwise load the installed extension's bundled wheels ahead of the venv's packages)."""
    import os

    env = {k: v for k, v in os.environ.items() if k != "BLENDER_USER_RESOURCES"}
    env["PYTHONPATH"] = str(ROOT)
    env.update(overrides)
    return env


def random_queries(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 6) uniform queries: u, v in [0, 1), θ in [0, 90°), φ in [0, 360°)."""
    return np.column_stack(
        [
            rng.random(n),
            rng.random(n),
            rng.random(n) * 90,
            rng.random(n) * 360,
            rng.random(n) * 90,
            rng.random(n) * 360,
        ]
    )


def run_python(*args, check=True, cwd=ROOT, env=None) -> subprocess.CompletedProcess:
    """This venv's Python in a subprocess (``-m btf_addon …`` or ``-c CODE``), with this
    checkout importable; ``check`` asserts exit code 0 and shows stderr otherwise."""
    proc = subprocess.run(
        [sys.executable, *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
        env=env or cli_env(),
    )
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def run_cli(*args, check=True, cwd=ROOT, env=None) -> subprocess.CompletedProcess:
    """``python -m btf_addon ARGS`` in a subprocess."""
    return run_python("-m", "btf_addon", *args, check=check, cwd=cwd, env=env)

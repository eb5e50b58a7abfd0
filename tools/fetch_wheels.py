"""Download the wheels that blender_manifest.toml bundles, for every platform it lists.

The manifest's ``wheels`` list is the single source of truth: each entry's file name says the
package, version and platform tags, and this script asks pip for exactly that file, or, for
the per-platform wheels that tools/slim_wheels.py cuts from a published all-platform one,
derives it. Files already present are kept, so the target is cheap to repeat.
"""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

from slim_wheels import SLIM, fetch_and_derive  # same folder: run as a script

ROOT = Path(__file__).resolve().parent.parent


def wheel_paths(manifest: Path = ROOT / "blender_manifest.toml") -> list[Path]:
    with manifest.open("rb") as fh:
        data = tomllib.load(fh)
    return [ROOT / entry for entry in data.get("wheels", [])]


def python_version_of_tag(python_tag: str) -> str:
    """``cp313`` → ``3.13``: the Python a CPython-specific wheel is built for."""
    if not (python_tag.startswith("cp3") and python_tag[2:].isdigit()):
        raise ValueError(f"not a CPython 3 wheel tag: {python_tag!r}")
    return f"3.{python_tag[3:]}"


def pip_download_args(wheel: Path) -> list[str]:
    """pip arguments that fetch exactly ``wheel`` (name-version-python-abi-platform.whl).

    pip's cache (``~/.cache/pip``) is used as usual, so the test environments and this script
    download each file once."""
    name, version, python_tag, abi_tag, platform_tag = wheel.name[: -len(".whl")].split("-")
    args = ["--no-deps", "--only-binary=:all:", "-d", str(wheel.parent)]
    if platform_tag != "any":
        if abi_tag != "none":  # a CPython build; "py2.py3-none-<platform>" (PoCL) fits any
            args += ["--python-version", python_version_of_tag(python_tag)]
            args += ["--implementation", "cp", "--abi", abi_tag]
        for tag in platform_tag.split("."):
            args += ["--platform", tag]
    return [*args, f"{name}=={version}"]


def main() -> int:
    missing = [w for w in wheel_paths() if not w.exists()]
    for wheel in missing:
        wheel.parent.mkdir(parents=True, exist_ok=True)
        if wheel.name in SLIM:  # cut from a published all-platform wheel (tools/slim_wheels.py)
            print(f"deriving {wheel.name} from {SLIM[wheel.name].source}", flush=True)
            try:
                fetch_and_derive(wheel)
            except subprocess.CalledProcessError:
                print(f"error: pip could not download {SLIM[wheel.name].source}", file=sys.stderr)
                return 1
            continue
        print(f"fetching {wheel.name}", flush=True)
        cmd = [sys.executable, "-m", "pip", "download", "-q", *pip_download_args(wheel)]
        if subprocess.run(cmd, check=False).returncode != 0:
            print(
                f"error: pip could not download {wheel.name}; is PyPI reachable?", file=sys.stderr
            )
            return 1
        if not wheel.exists():
            print(f"error: pip downloaded a different file than {wheel.name}", file=sys.stderr)
            return 1
    print(f"wheels: {len(wheel_paths())} present in {ROOT / 'wheels'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

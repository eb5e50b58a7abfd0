"""Build and validate the extension with Blender's own builder (bl_pkg's blender_ext.py).

That script ships inside the bpy wheel and is the same code as ``blender --command extension
build``; running it with plain Python avoids starting Blender. Tags are validated against the list
Blender itself uses (``_bpy_internal/extensions/tags.py``), as ``blender --command`` does.
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
from pathlib import Path

from fetch_wheels import wheel_paths  # same folder: run as a script, tools/ is on sys.path

ROOT = Path(__file__).resolve().parent.parent


def blender_scripts_dir() -> Path:
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("error: the bpy module is not installed; run `make setup` first")
    bpy_dir = Path(next(iter(spec.submodule_search_locations)))
    versions = sorted(p for p in bpy_dir.iterdir() if p.is_dir() and p.name[:1].isdigit())
    if not versions:
        raise SystemExit(f"error: no Blender version folder inside {bpy_dir}")
    return versions[-1] / "scripts"


def blender_ext_command(*args: str) -> list[str]:
    scripts = blender_scripts_dir()
    tool = scripts / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"
    tags = scripts / "modules" / "_bpy_internal" / "extensions" / "tags.py"
    return [sys.executable, str(tool), *args, f"--valid-tags={tags}"]


def build(output_dir: Path, split_platforms: bool) -> list[Path]:
    output_dir.mkdir(parents=True, exist_ok=True)
    for stale in output_dir.glob("btf_materials-*.zip"):
        stale.unlink()  # only this build's zips may be validated and reported below
    cmd = blender_ext_command("build", "--source-dir", str(ROOT), "--output-dir", str(output_dir))
    if split_platforms:
        cmd.append("--split-platforms")
    subprocess.run(cmd, check=True)
    zips = sorted(output_dir.glob("btf_materials-*.zip"))
    for zip_path in zips:
        subprocess.run(blender_ext_command("validate", str(zip_path)), check=True)
    return zips


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--output-dir", type=Path, default=ROOT / "dist")
    parser.add_argument("--no-split", action="store_true", help="one zip for all platforms")
    args = parser.parse_args()
    missing = [w for w in wheel_paths() if not w.exists()]
    if missing:
        print(
            f"error: {len(missing)} bundled wheels are missing; run `make wheels`", file=sys.stderr
        )
        return 1
    try:
        zips = build(args.output_dir, split_platforms=not args.no_split)
    except subprocess.CalledProcessError:
        print(
            "error: Blender's extension builder rejected the package (see above)", file=sys.stderr
        )
        return 1
    for zip_path in zips:
        # The Linux zip is the largest: it bundles PoCL, the CPU OpenCL driver (~58 MB).
        size_mb = zip_path.stat().st_size / 1e6
        print(f"built and validated {zip_path} ({size_mb:.0f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Per-platform wheels cut from a published all-platform wheel: only the files that run.

pyopenxr's one wheel (``py3-none-any``, 57 MB, ~220 MB unpacked) carries the OpenXR loader for
seven platforms and the Khronos API layers (api dump, core and best-practice validation) for
each; the XTAL bridge loads the loader of its own platform and never an API layer. Bundling
it whole made every zip 57 MB heavier. ``SLIM`` names, per derived wheel, the published wheel
it comes from and the files it keeps; the derived wheel is a valid wheel (WHEEL tag and RECORD
rewritten) whose platform tag lets Blender's builder put it in that platform's zip only.

What each derived pyopenxr wheel keeps, and why:
- every ``xr/**.py`` module: ``import xr`` imports all of them (``xr/api_layer`` included,
  which sets XR_API_LAYER_PATH to its platform folder, where no layer manifest is left, and
  loads that folder's ``XrApiLayer_python`` dispatch library, which is kept: no layer itself);
- ``xr/library/<platform>/`` with that platform's loader (``libopenxr_loader.so`` or
  ``openxr_loader.dll``), which ``xr/library/__init__.py`` loads by ``platform_folder()``;
- the ``.dist-info`` metadata (rewritten).
Dropped: the other platforms' loaders (Android, aarch64, win32, the top-level copies that
``platform_folder()`` never names) and every API layer library and manifest (api dump, core
and best-practice validation). pyopenxr has no macOS loader at all, so the macOS wheel keeps
the modules alone: ``import xr`` fails there as it does with the published wheel, and the
bridge says so.

Run by tools/fetch_wheels.py; ``python tools/slim_wheels.py WHEEL…`` rebuilds given ones.
"""

from __future__ import annotations

import base64
import hashlib
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Slim:
    source: str  # the published wheel's file name
    loader_folder: str | None  # xr/library/<folder> kept (None: no loader for this platform)


PYOPENXR = "pyopenxr-1.1.6501-py3-none-any.whl"

#: Derived wheel file name → how it is cut.
SLIM: dict[str, Slim] = {
    "pyopenxr-1.1.6501-py3-none-manylinux_2_17_x86_64.whl": Slim(PYOPENXR, "linux_x86_64"),
    "pyopenxr-1.1.6501-py3-none-win_amd64.whl": Slim(PYOPENXR, "windows_x86_64"),
    "pyopenxr-1.1.6501-py3-none-macosx_11_0_arm64.whl": Slim(PYOPENXR, None),
}


def keeps(path: str, slim: Slim) -> bool:
    """Whether the derived wheel keeps the published wheel's file ``path``."""
    if path.endswith("/"):
        return False  # directory entries: wheels need none
    if ".dist-info/" in path:
        return not path.endswith(("/RECORD", "/WHEEL"))  # both are rewritten
    if path.startswith("xr/library/"):
        rest = path[len("xr/library/") :]
        if rest == "__init__.py":
            return True
        return slim.loader_folder is not None and rest.startswith(slim.loader_folder + "/")
    if path.startswith("xr/api_layer/"):
        if path.endswith(".py"):
            return True
        # The dispatch library `import xr` loads (xr/api_layer/raw_functions.py): it is no
        # layer, the loader's hook for layers written in Python (~0.1 MB).
        name = path.rsplit("/", 1)[-1]
        return (
            slim.loader_folder is not None
            and path.startswith(f"xr/api_layer/{slim.loader_folder}/")
            and name in ("libXrApiLayer_python.so", "XrApiLayer_python.dll")
        )
    return path.startswith("xr/")


def _record_line(name: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def derive(source: Path, target: Path, slim: Slim) -> None:
    """Write ``target`` (a derived wheel) from ``source`` (the published one), atomically."""
    tag = target.name[: -len(".whl")].split("-", 2)[2]  # py3-none-<platform>
    with zipfile.ZipFile(source) as zin:
        names = zin.namelist()
        dist_info = next(n.split("/")[0] for n in names if n.endswith(".dist-info/WHEEL"))
        files = {n: zin.read(n) for n in names if keeps(n, slim)}
    files[f"{dist_info}/WHEEL"] = (
        "Wheel-Version: 1.0\n"
        "Generator: btf_materials tools/slim_wheels.py\n"
        "Root-Is-Purelib: true\n"
        f"Tag: {tag}\n"
    ).encode()
    record = [_record_line(n, d) for n, d in sorted(files.items())]
    record.append(f"{dist_info}/RECORD,,")
    files[f"{dist_info}/RECORD"] = ("\n".join(record) + "\n").encode()
    partial = target.with_name(target.name + ".partial")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zout:
        for name in sorted(files):
            info = zipfile.ZipInfo(name, date_time=(2026, 1, 1, 0, 0, 0))  # reproducible
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = (0o755 if name.endswith((".so", ".dll")) else 0o644) << 16
            zout.writestr(info, files[name])
    partial.replace(target)


def fetch_and_derive(target: Path) -> None:
    """Download the published wheel ``SLIM[target.name]`` names (pip's cache makes a second
    fetch free) and write ``target`` from it."""
    slim = SLIM[target.name]
    with tempfile.TemporaryDirectory() as tmp:
        name, version = slim.source.split("-")[:2]
        cmd = [sys.executable, "-m", "pip", "download", "-q", "--no-deps"]
        cmd += ["--only-binary=:all:", "-d", tmp, f"{name}=={version}"]
        subprocess.run(cmd, check=True)
        derive(Path(tmp) / slim.source, target, slim)


if __name__ == "__main__":
    for arg in sys.argv[1:]:
        fetch_and_derive(Path(arg))
        print(f"derived {arg}")

"""Builds the BTF test OpenXR runtime (C) into a shared library and writes its loader manifest.

The runtime is a test double at a hardware boundary: the real OpenXR loader (bundled with
pyopenxr) loads it through ``XR_RUNTIME_JSON``. It needs the system C compiler (``cc``), the
OpenXR headers (Debian ``libopenxr-dev``) and the EGL/GL headers (``libegl-dev``, ``libgl-dev``);
no library is linked beyond libc and libm (GL and EGL come through the app's getProcAddress).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

SOURCE_DIR = Path(__file__).resolve().parent
LIBRARY_NAME = "libbtf_test_runtime.so"
MANIFEST_NAME = "btf_test_runtime.json"
RUNTIME_NAME = "BTF test runtime"

# header -> the Debian package that installs it
HEADERS = {
    "openxr/openxr_platform.h": "libopenxr-dev",
    "openxr/openxr_reflection.h": "libopenxr-dev",
    "EGL/egl.h": "libegl-dev",
    "GL/gl.h": "libgl-dev",
}
CFLAGS = ["-std=gnu11", "-shared", "-fPIC", "-pthread", "-O1", "-g", "-Wall", "-Wextra", "-Werror"]
# only xrNegotiateLoaderRuntimeInterface is exported: everything else goes through the loader
CFLAGS += ["-fvisibility=hidden"]


class RuntimeBuildError(RuntimeError):
    """The test runtime cannot be built here (a missing compiler or header, or a compile error)."""


def sources() -> list[Path]:
    return sorted(SOURCE_DIR.glob("*.c")) + sorted(SOURCE_DIR.glob("*.h"))


def missing_tools(include_dir: Path = Path("/usr/include")) -> list[str]:
    """What the build lacks, each as 'what (apt package)'; empty when everything is there."""
    missing = []
    if not (os.environ.get("CC") or shutil.which("cc")):
        missing.append("the C compiler cc (apt install gcc)")
    for header, package in HEADERS.items():
        if not (include_dir / header).is_file():
            missing.append(f"{include_dir / header} (apt install {package})")
    return missing


def build_runtime(out_dir: Path) -> Path:
    """Compile the runtime into ``out_dir`` (only when a source is newer than the library) and
    write the loader manifest there. Returns the manifest's path (for ``XR_RUNTIME_JSON``).

    Raises RuntimeBuildError naming the missing compiler/header and its apt package.
    """
    out_dir = Path(out_dir).resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    library = out_dir / LIBRARY_NAME
    srcs = sources()
    newest = max(p.stat().st_mtime for p in srcs)
    # BTF_XR_RUNTIME_CFLAGS adds flags (e.g. -fsanitize=address); a change of flags rebuilds
    extra = os.environ.get("BTF_XR_RUNTIME_CFLAGS", "").split()
    stamp = out_dir / "build_flags.txt"
    flags_changed = not stamp.exists() or stamp.read_text() != " ".join(extra)
    if not library.exists() or library.stat().st_mtime < newest or flags_changed:
        missing = missing_tools()
        if missing:
            raise RuntimeBuildError(
                "cannot build the OpenXR test runtime: missing " + "; ".join(missing)
            )
        cc = os.environ.get("CC") or shutil.which("cc")
        tmp = library.with_name(library.name + f".{os.getpid()}.tmp")
        c_files = [str(p) for p in srcs if p.suffix == ".c"]
        cmd = [cc, *CFLAGS, *extra, "-o", str(tmp), *c_files, "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            tmp.unlink(missing_ok=True)
            raise RuntimeBuildError(
                f"compiling the OpenXR test runtime failed ({' '.join(cmd)}):\n{proc.stderr}"
            )
        os.replace(tmp, library)  # atomic: a concurrent loader never sees half a library
        stamp.write_text(" ".join(extra))
    manifest = out_dir / MANIFEST_NAME
    text = json.dumps(
        {
            "file_format_version": "1.0.0",
            "runtime": {"name": RUNTIME_NAME, "library_path": str(library)},
        },
        indent=2,
    )
    if not manifest.exists() or manifest.read_text() != text:
        manifest.write_text(text)
    return manifest


if __name__ == "__main__":
    import sys

    print(build_runtime(Path(sys.argv[1] if len(sys.argv) > 1 else "build/xr_runtime")))

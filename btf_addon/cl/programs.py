"""Build OpenCL programs from kernels/*.cl, cached in memory and on disk.

Every build gets the packed table layout (core/codecs/packed.py ``defines()``: header slots, codec
ids) as ``-D`` options beside the caller's variant defines. Key: (platform, device, driver
version, the full define set, hash of the source as compiled, i.e. the .cl with its headers
expanded). The second build of the same key in a process is free; in a new process the device
binary is loaded from the disk cache, so a render does not wait for the compiler again.
A kernel that does not compile raises ``OpenCLCompileError`` (never "no device"); its build log
names kernels/<file> and line through the ``#line`` directives ``expand_includes`` writes.
Set BTF_CL_BUILD_LOG=1 to print compiler logs; BTF_CL_CACHE (or ``set_cache_dir``) to move the
disk cache. A cache folder that cannot be written falls back to a temporary one (and says so):
a cache is never a reason to fail.
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
from pathlib import Path

from ..core.codecs import packed
from ..core.errors import BuildError
from ..core.fileio import atomic_write, user_cache_root

log = logging.getLogger(__name__)

KERNELS_DIR = Path(__file__).resolve().parents[2] / "kernels"
_memory_cache: dict[str, object] = {}


class OpenCLCompileError(BuildError):
    """A kernel failed to compile: a bug in kernels/ or a driver that rejects valid code, never
    "no device". ``build_log`` holds the compiler's messages."""

    def __init__(self, kernel: str, device_name: str, build_log: str):
        self.kernel, self.device_name, self.build_log = kernel, device_name, build_log
        super().__init__(
            f"OpenCL compile of {kernel} failed on {device_name}:\n{build_log.strip()}"
        )


stats = {"compiled": 0, "disk_hits": 0, "memory_hits": 0}


#: Set by ``set_cache_dir`` (Blender: the extension's user directory); None: the default.
_cache_dir_setting: Path | None = None
#: Folder asked for → folder used (itself, or a temporary one when it cannot be written).
_resolved: dict[Path, Path] = {}
#: Folders found unwritable, with the reason: what the OpenCL diagnosis names.
unwritable_folders: dict[str, str] = {}


def set_cache_dir(path: str | Path | None) -> None:
    """Keep compiled kernels in ``path`` (None: back to the default, ``BTF_CL_CACHE`` or
    ``$XDG_CACHE_HOME/btf_materials/opencl``). Blender's register points it into the
    extension's user directory, so the cache goes when the extension is removed."""
    global _cache_dir_setting
    _cache_dir_setting = Path(path) if path is not None else None


def configured_cache_dir() -> Path:
    """The folder asked for, before any fallback."""
    if _cache_dir_setting is not None:
        return _cache_dir_setting
    if env := os.environ.get("BTF_CL_CACHE"):
        return Path(env)
    return user_cache_root() / "btf_materials" / "opencl"


def cache_dir() -> Path:
    """The kernel cache folder in use: the configured one where it can be written, else a
    private folder under the system's temporary directory (logged once, naming the folder
    that could not be written, and listed in ``unwritable_folders``)."""
    wanted = configured_cache_dir()
    if wanted not in _resolved:
        _resolved[wanted] = _usable(wanted, "opencl")
    return _resolved[wanted]


def _write_problem(folder: Path) -> str | None:
    """Why ``folder`` cannot hold cache files (None: it can). Tried for real, by creating it
    and a file in it: permission bits say nothing for root, read-only mounts or a file in
    the way."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(prefix=".write-test.", dir=folder)
        os.close(fd)
        os.unlink(name)
        return None
    except OSError as exc:
        return exc.strerror or str(exc)


def _usable(wanted: Path, kind: str) -> Path:
    problem = _write_problem(wanted)
    if problem is None:
        return wanted
    uid = os.getuid() if hasattr(os, "getuid") else os.getpid()
    fallback = Path(tempfile.gettempdir()) / f"btf_materials-{uid}" / kind
    unwritable_folders[str(wanted)] = problem
    log.warning(
        "the %s cache folder %s cannot be written (%s); using %s instead",
        kind,
        wanted,
        problem,
        fallback,
    )
    return fallback


def prepare_driver_caches() -> None:
    """Before the OpenCL platforms load: PoCL keeps its own kernel cache (``POCL_CACHE_DIR``,
    default ``$XDG_CACHE_HOME/pocl``) and reports *no device* when it cannot create it;
    pyopencl and pytools cache under ``$XDG_CACHE_HOME`` and raise. Where those folders cannot
    be written (sandboxes, farms, a read-only HOME) they are pointed at temporary ones, and the
    folder that failed is logged and kept in ``unwritable_folders`` for the diagnosis."""
    base = user_cache_root()
    pocl = Path(os.environ.get("POCL_CACHE_DIR") or base / "pocl")
    used = _usable(pocl, "pocl")
    if used != pocl:
        os.environ["POCL_CACHE_DIR"] = str(used)
    if _write_problem(base) is not None:
        os.environ["XDG_CACHE_HOME"] = str(_usable(base, "xdg-cache"))


def cache_diagnosis() -> str:
    """'; cache folders that could not be written: …' for error messages ('' when none)."""
    if not unwritable_folders:
        return ""
    listed = ", ".join(f"{k} ({v})" for k, v in unwritable_folders.items())
    return f"; cache folders that could not be written (temporary ones used instead): {listed}"


def source_name(path: Path) -> str:
    """How compiler messages name a source file: relative to the repository (kernels/x.cl,
    kernels/include/x.h) when it lies there, else its full path."""
    try:
        return path.resolve().relative_to(KERNELS_DIR.parent).as_posix()
    except ValueError:
        return path.resolve().as_posix()


def expand_includes(path: Path, seen: set[Path] | None = None) -> str:
    """The source with ``#include "x.h"`` lines replaced by kernels/include/x.h (once each; a
    ``.inc`` file, a template written for the type its includer defines, at every include).

    Done here rather than with ``-I``: install paths may contain spaces or non-ASCII characters
    that OpenCL compilers' option parsing handles differently, and the text hashed for the cache
    is then exactly the text compiled. ``#line`` directives before and after every expanded
    header keep compiler messages at the real file and line (kernels/include/x.h:12)."""
    seen = set() if seen is None else seen
    name = source_name(path).replace('"', "")  # a quote would end the #line string
    out = [f'#line 1 "{name}"']
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        stripped = line.strip()
        if stripped.startswith('#include "') and stripped.endswith('"'):
            header = KERNELS_DIR / "include" / stripped[len('#include "') : -1]
            if header not in seen:
                if header.suffix != ".inc":
                    seen.add(header)
                out.append(expand_includes(header, seen))
            out.append(f'#line {number + 1} "{name}"')  # back in this file, after the include
            continue
        out.append(line)
    return "\n".join(out)


def build_defines(defines: dict[str, int | float]) -> dict[str, int | float]:
    """The packed layout's defines plus a program's own variant defines (which may not
    redefine a layout name: the layout has one definition)."""
    layout = packed.defines()
    clash = sorted(set(layout) & set(defines))
    if clash:
        raise ValueError(f"program defines {clash} would override the packed table layout")
    return {**layout, **defines}


def _options(defines: dict[str, int | float]) -> list[str]:
    return [f"-D{k}={v}" for k, v in sorted(build_defines(defines).items())]


def program_key(device, name: str, defines: dict[str, int | float]) -> str:
    digest = hashlib.sha256(expand_includes(KERNELS_DIR / name).encode()).hexdigest()
    ident = "|".join(
        [
            device.platform.name,
            device.name,
            device.driver_version,
            " ".join(_options(defines)),
            digest,
        ]
    )
    return hashlib.sha256(ident.encode()).hexdigest()[:32]


def is_cached(context, device, name: str, defines: dict[str, int | float]) -> bool:
    """Whether build_program will find this program built (memory) or as a binary (disk), so
    callers can say "compiling…" before a first build that may take a minute."""
    key = program_key(device, name, defines)
    return f"{context.int_ptr}:{key}" in _memory_cache or (cache_dir() / f"{key}.bin").is_file()


def build_program(context, device, name: str, defines: dict[str, int | float]):
    """The built ``cl.Program`` for kernels/<name> with ``-D`` defines on one device."""
    import pyopencl as cl

    key = program_key(device, name, defines)
    memory_key = f"{context.int_ptr}:{key}"  # a built program belongs to its context
    if memory_key in _memory_cache:
        stats["memory_hits"] += 1
        return _memory_cache[memory_key]
    options = _options(defines)
    binary_path = cache_dir() / f"{key}.bin"
    program = None
    if binary_path.is_file():
        try:
            program = cl.Program(context, [device], [binary_path.read_bytes()]).build(options)
            stats["disk_hits"] += 1
        except cl.Error as exc:  # a stale or foreign binary: rebuild from source below
            log.info("ignoring cached OpenCL binary %s (%s)", binary_path.name, exc)
            program = None
    if program is None:
        source = expand_includes(KERNELS_DIR / name)
        unbuilt = cl.Program(context, source)
        try:
            # pyopencl's own source cache beside ours (it would otherwise use ~/.cache).
            program = unbuilt.build(
                options, devices=[device], cache_dir=str(cache_dir() / "pyopencl")
            )
        except cl.RuntimeError as exc:
            try:
                build_log = unbuilt.get_build_info(device, cl.program_build_info.LOG)
            except cl.Error:
                build_log = ""
            raise OpenCLCompileError(
                source_name(KERNELS_DIR / name), device.name.strip(), build_log or str(exc)
            ) from None
        stats["compiled"] += 1
        _store_binary(program, binary_path)
    if os.environ.get("BTF_CL_BUILD_LOG"):
        log.warning(
            "build log %s on %s:\n%s",
            name,
            device.name,
            program.get_build_info(device, cl.program_build_info.LOG),
        )
    _memory_cache[memory_key] = program
    return program


def _store_binary(program, path: Path) -> None:
    """Write the device binary atomically; a cache that cannot be written is not an error."""
    import pyopencl as cl

    try:
        binary = program.get_info(cl.program_info.BINARIES)[0]
        atomic_write(path, lambda fh: fh.write(binary))
    except (OSError, cl.Error) as exc:
        log.info("OpenCL binary cache not written (%s)", exc)

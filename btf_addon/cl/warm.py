"""pyopencl imported ahead of the first F12, on a thread of its own.

Importing pyopencl (its pytools dependency reads package metadata, its type tables build) was
paid by the first F12 of every Blender process: the demo's F12 at the benchmark's 64×48 and 64
samples, fresh processes, took 0.306 s with it and 0.281 s without (medians of 8; cProfile puts
the import at ~50 ms, its own overhead included). docs/accuracy.md, "Time to reach the same
error". Cycles loads its own library when Blender starts. Here the enabled extension
starts the import on a thread at registration, so it runs while Blender loads the file and
builds the scene; F12 then finds the module (or waits for the rest of it on Python's import
lock: never a second import).

Only the module and the system's OpenCL ICD loader (the library pyopencl links) load here: no
driver. The loader opens the vendors' drivers at the first platform query, which stays in F12
(cl/devices.py), where the user asked for OpenCL. A failed import is silent here; F12 makes the
same import and reports it in Blender's words (blender/final_render.py).

The platform query itself starts at the top of F12 (``query_platforms``), on a thread again:
the loader opening PoCL is ~20–30 ms that pyopencl's ``get_platforms`` spends holding Python's
lock, so a thread calling it would only stall the export. The thread calls the same loader
through ctypes, which lets go of the lock for the call; the scene's export runs meanwhile on the
other core, and pyopencl's own query afterwards finds the platforms already open.
"""

from __future__ import annotations

import ctypes
import os
import sys
import threading

__all__ = ["query_platforms", "start", "wait", "wait_for_platforms"]

_thread: threading.Thread | None = None
_platforms_thread: threading.Thread | None = None


def _import() -> None:
    try:
        # The import is the work, with what pyopencl imports at a program's first build and
        # a kernel's first call.
        import pyopencl.characterize
        import pyopencl.invoker  # noqa: F401
    except Exception:  # missing or broken: F12's own import says what to do
        pass


def start() -> None:
    """Start importing pyopencl on a thread, once per process; nothing when it is loaded."""
    global _thread
    if _thread is not None or "pyopencl" in sys.modules:
        return
    # numpy first, on this thread: pyopencl imports it, and two threads each holding one
    # module's import lock while waiting for the other's is the one way an import deadlocks.
    import numpy  # noqa: F401

    # Not a daemon: an interpreter that exits meanwhile waits for the import to finish instead
    # of tearing a half-initialised extension module down under it.
    _thread = threading.Thread(target=_import, name="btf-import-pyopencl")
    _thread.start()


def wait(timeout: float | None = None) -> bool:
    """Wait for a started import; True when none is running (any more)."""
    thread = _thread
    if thread is None:
        return True
    thread.join(timeout)
    return not thread.is_alive()


def _loader_path() -> str | None:
    """The OpenCL ICD loader pyopencl runs on, as this process mapped it (Linux: /proc), so
    that ctypes opens that very library and its state, not another copy; None elsewhere."""
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as maps:
            for line in maps:
                path = line.rstrip("\n").split(maxsplit=5)[-1]
                if "/libOpenCL" in path and path.startswith("/"):
                    return path
    except OSError:
        pass
    return None


def _open_platforms() -> None:
    try:
        import pyopencl  # noqa: F401  (maps the loader; waits for start()'s import if running)
    except Exception:
        return  # F12's own import reports it
    path = _loader_path()
    if not path:
        return  # not Linux: F12's own query does all of it, as before
    try:
        # RTLD_NOLOAD: the library already mapped, or an error; never a second copy
        loader = ctypes.CDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_LAZY)
        count = ctypes.c_uint32(0)
        if loader.clGetPlatformIDs(0, None, ctypes.byref(count)) != 0 or not count.value:
            return
        ids = (ctypes.c_void_p * count.value)()
        loader.clGetPlatformIDs(count.value, ids, None)
        all_types = ctypes.c_uint64(0xFFFFFFFF)  # CL_DEVICE_TYPE_ALL
        for platform in ids:  # PoCL finishes its devices' set-up at the first device query
            found = ctypes.byref(count)
            loader.clGetDeviceIDs(ctypes.c_void_p(platform), all_types, 0, None, found)
    except (OSError, AttributeError):  # a loader without these symbols: F12 reports it
        pass


def query_platforms() -> None:
    """Start the OpenCL platform query on a thread, once per process (F12's first call)."""
    global _platforms_thread
    if _platforms_thread is not None:
        return
    from .programs import prepare_driver_caches

    prepare_driver_caches()  # here, before the thread: the drivers read them as they load
    _platforms_thread = threading.Thread(target=_open_platforms, name="btf-opencl-platforms")
    _platforms_thread.start()


def wait_for_platforms() -> None:
    """Before any pyopencl call of the platforms: the loader is never entered from two threads
    at once (loaders differ in how they lock their first call)."""
    thread = _platforms_thread
    if thread is not None:
        thread.join()

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
"""

from __future__ import annotations

import sys
import threading

__all__ = ["start", "wait"]

_thread: threading.Thread | None = None


def _import() -> None:
    try:
        import pyopencl  # noqa: F401  (the import is the work)
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

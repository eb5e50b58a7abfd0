"""cl/warm.py: pyopencl imported on a thread of its own, so the first F12 does not pay for it;
nothing said where pyopencl cannot be imported (F12 says it). Each case in a fresh Python: in
this process pyopencl is long imported."""

from __future__ import annotations

from helpers import run_python

CHECK = """
import sys, threading
from btf_addon.cl import warm
assert "pyopencl" not in sys.modules
warm.start()
warm.start()  # once per process
threads = [t for t in threading.enumerate() if t.name == "btf-import-pyopencl"]
assert len(threads) <= 1, threads
assert warm.wait(120), "the import did not finish"
print("pyopencl" in sys.modules and sys.modules["pyopencl"] is not None)
"""


def test_start_imports_pyopencl_on_a_thread():
    proc = run_python("-c", CHECK)
    assert proc.stdout.split() == ["True"], proc.stdout + proc.stderr
    assert proc.stderr == ""


def test_an_unimportable_pyopencl_is_left_to_f12_to_report():
    # An import hook that refuses pyopencl, as on a machine without it (ImportError).
    code = (
        "import builtins\n"
        "real = builtins.__import__\n"
        "def refuse(name, *a, **k):\n"
        "    if name == 'pyopencl':\n"
        "        raise ImportError('no pyopencl here')\n"
        "    return real(name, *a, **k)\n"
        "builtins.__import__ = refuse\n"
    )
    proc = run_python("-c", code + CHECK)
    # The thread ended, pyopencl absent, and no traceback from the thread on stderr.
    assert proc.stdout.split() == ["False"], proc.stdout + proc.stderr
    assert proc.stderr == ""


def test_wait_without_a_start_returns_at_once():
    proc = run_python("-c", "from btf_addon.cl import warm; print(warm.wait(0.0))")
    assert proc.stdout.split() == ["True"]

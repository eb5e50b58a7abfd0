"""cl/warm.py: pyopencl imported on a thread of its own, so the first F12 does not pay for it;
nothing said where pyopencl cannot be imported (F12 says it). Each case in a fresh Python: in
this process pyopencl is long imported."""

from __future__ import annotations

import sys

import pytest
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


# The libraries mapped before and after the platforms are listed through pyopencl; with
# ``query_platforms`` first, the drivers are already mapped (its thread opened them).
PLATFORMS = """
import json, sys, threading
from btf_addon.cl import devices, programs, warm

def libraries():
    with open("/proc/self/maps") as maps:
        return {line.split()[-1] for line in maps if ".so" in line.split()[-1]}

import pyopencl  # noqa: F401  (the loader, mapped either way)
programs.prepare_driver_caches()
if QUERY:
    warm.query_platforms()
    warm.query_platforms()  # once per process
    names = [t.name for t in threading.enumerate() if t.name == "btf-opencl-platforms"]
    assert len(names) <= 1, names
    warm.wait_for_platforms()
before = libraries()
listed = [d.to_json() for d in devices.list_devices()]
print(json.dumps({"new": sorted(before.symmetric_difference(libraries())), "devices": listed}))
"""


def _platforms_run(query: bool) -> dict:
    import json

    proc = run_python("-c", f"QUERY = {query}\n" + PLATFORMS)
    assert proc.stderr == "", proc.stderr
    return json.loads(proc.stdout.splitlines()[-1])


def test_query_platforms_opens_the_drivers_on_its_thread():
    if not sys.platform.startswith("linux"):
        pytest.skip("query_platforms finds the loader through /proc (Linux); elsewhere a no-op")
    plain, queried = _platforms_run(False), _platforms_run(True)
    # The control: without the thread, listing the devices maps the drivers (else this test
    # could not tell the two apart).
    assert plain["new"], "listing the devices mapped no driver: nothing to compare"
    assert queried["new"] == [], queried["new"]
    # and pyopencl then sees exactly the devices it sees without the thread
    assert queried["devices"] == plain["devices"]
    assert plain["devices"], "no OpenCL device on this machine"

"""core/fileio.py: the one atomic write every file writer goes through."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core import fileio
from btf_addon.core.fileio import atomic_write, atomic_write_path


def test_writes_through_a_handle_and_creates_the_folder(tmp_path):
    target = tmp_path / "new" / "a.npy"
    atomic_write(target, lambda fh: np.save(fh, np.arange(3)))
    assert np.array_equal(np.load(target), np.arange(3))
    assert sorted(p.name for p in target.parent.iterdir()) == ["a.npy"]


def test_writes_by_name_for_writers_that_need_one(tmp_path):
    target = tmp_path / "b.bin"
    seen = []

    def write(path):
        seen.append(path)
        path.write_bytes(b"by name")

    atomic_write_path(target, write)
    assert target.read_bytes() == b"by name"
    assert seen[0].parent == tmp_path and seen[0] != target and seen[0].suffix == ".bin"
    assert not seen[0].exists()  # renamed over the target


@pytest.mark.parametrize("writer", [atomic_write, atomic_write_path])
def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path, writer):
    target = tmp_path / "c.dat"
    target.write_bytes(b"old")

    def fail(_):
        raise KeyboardInterrupt  # also an interrupt, not only an Exception

    with pytest.raises(KeyboardInterrupt):
        writer(target, fail)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["c.dat"]


def _dead_pid() -> int:
    """A process id that existed and is gone (a child that has exited and been reaped)."""
    import subprocess
    import sys

    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_temporaries_carry_the_pid_and_stale_ones_are_removed_on_the_next_write(tmp_path):
    import os

    target = tmp_path / "d.npy"
    seen = []
    atomic_write_path(target, lambda p: (seen.append(p.name), p.write_bytes(b"x")))
    host = fileio._host()
    assert seen[0].startswith(f".d.pid{os.getpid()}-{host}.") and seen[0].endswith(".tmp.npy")
    stale = tmp_path / f".d.pid{_dead_pid()}-{host}.abc.tmp.npy"  # a killed writer's leftover
    live = tmp_path / f".d.pid{os.getppid()}-{host}.abc.tmp.npy"  # a concurrent writer: kept
    other = tmp_path / f".e.pid{_dead_pid()}-{host}.abc.tmp.npy"  # another target's: not judged
    remote = tmp_path / f".d.pid{_dead_pid()}-elsewhere.abc.tmp.npy"  # another machine's pids
    for p in (stale, live, other, remote):
        p.write_bytes(b"partial")
    atomic_write(target, lambda fh: fh.write(b"y"))
    assert not stale.exists() and live.exists() and other.exists() and remote.exists()
    assert target.read_bytes() == b"y"


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_outputs_honour_the_umask(tmp_path, umask):
    import os

    previous = os.umask(umask)
    try:
        a = atomic_write(tmp_path / "a.bin", lambda fh: fh.write(b"a"))
    finally:
        os.umask(previous)
    assert a.stat().st_mode & 0o777 == 0o666 & ~umask

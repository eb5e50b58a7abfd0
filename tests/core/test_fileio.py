"""core/fileio.py: the one atomic write every file writer goes through."""

from __future__ import annotations

import numpy as np
import pytest

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

"""An output the commands cannot write is said first, naming the output (issue 30 item 16):
``-o`` at a folder, under a file, or where no file can be made; and a failing write (a full
disk) names the output, not the temporary file it was going to become."""

from __future__ import annotations

import errno

import numpy as np
import pytest
from helpers import run_cli, studiolights_dir

from btf_addon.core.errors import BTFError
from btf_addon.core.fileio import atomic_write, check_output


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("inputs")
    run_cli("synth", "lambertian", "--albedo", 0.5, "--tabulate", "ubo", "-o", folder / "l.btfm")
    q = np.array([[0.5, 0.5, 30, 0, 20, 90]], np.float32)
    np.save(folder / "q.npy", q)
    return folder


def _commands(inputs, out):
    exr = sorted(studiolights_dir().glob("*.exr"))[0]
    return {
        "eval": ["eval", inputs / "l.btfm", "--queries", inputs / "q.npy", "--out", out],
        "envmap": ["envmap", exr, "--lights", 4, "-o", out],
        "convert": ["convert", inputs / "l.btfm", out],
        "compress": ["compress", inputs / "l.btfm", "-o", out],
        "synth": ["synth", "lambertian", "-o", out],
    }


@pytest.mark.parametrize("command", ["eval", "envmap", "convert", "compress", "synth"])
def test_an_output_that_is_a_folder_is_named_and_refused(inputs, tmp_path, command):
    folder = tmp_path / "existing.npz"  # a folder whose name looks like the output's
    folder.mkdir()
    proc = run_cli(*_commands(inputs, folder)[command], check=False)
    assert proc.returncode == 2, proc.stderr
    assert f"error: {folder}: is a folder" in proc.stderr, proc.stderr
    assert ".tmp" not in proc.stderr and list(folder.iterdir()) == []


def test_an_output_under_a_file_is_named_and_refused(inputs, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    out = blocker / "sub" / "v.npy"
    proc = run_cli(*_commands(inputs, out)["eval"], check=False)
    assert proc.returncode == 2
    assert f"{out}: cannot be written: {blocker} is a file" in proc.stderr


def test_a_folder_where_no_file_can_be_made():
    """/proc takes no new files, not even from root (tests may run as root, for whom a
    chmod-ed folder is writable)."""
    with pytest.raises(BTFError, match=r"/proc/out\.npy: cannot write in /proc"):
        check_output("/proc/out.npy")


def test_a_full_disk_names_the_output_and_leaves_no_temporary(tmp_path):
    out = tmp_path / "v.npy"

    def full(fh):
        fh.write(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OSError) as caught:
        atomic_write(out, full)
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(out)
    assert list(tmp_path.iterdir()) == []


def test_a_signal_right_after_the_temporary_is_made_leaves_nothing(tmp_path, monkeypatch):
    """Issue 30 item 15: a SIGTERM between creating the temporary file and entering the
    cleanup left a 0-byte temporary. The signal here lands the moment mkstemp returns; it is
    handled inside the cleanup's reach, which knows the name before the file exists."""
    import os
    import signal

    class TerminatedError(Exception):
        pass

    def on_term(signum, frame):
        raise TerminatedError

    real_open = os.open

    def open_then_signal(name, *args, **kwargs):
        made = real_open(name, *args, **kwargs)
        if ".tmp" in str(name):  # the temporary now exists; its creator has not returned yet
            os.kill(os.getpid(), signal.SIGTERM)
        return made

    previous = signal.signal(signal.SIGTERM, on_term)
    monkeypatch.setattr(os, "open", open_then_signal)
    try:
        with pytest.raises(TerminatedError):
            atomic_write(tmp_path / "v.npy", lambda fh: fh.write(b"x"))
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert list(tmp_path.iterdir()) == []

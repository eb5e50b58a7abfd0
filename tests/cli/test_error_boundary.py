"""The CLI's one error boundary: every failure is one line with an exit code (2: bad input,
1: internal, 130: Ctrl-C or SIGTERM, temporaries removed); arguments that would give silent
wrong results are refused."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from helpers import ROOT, cli_env, make_blend, run_cli

from btf_addon.cli import btf_commands
from btf_addon.cli.main import main


@pytest.fixture(scope="module")
def material(tmp_path_factory):
    path = tmp_path_factory.mktemp("m") / "l.btfm"
    run_cli("synth", "lambertian", "-o", path)
    return path


def test_an_internal_error_is_one_line_exit_1_and_a_traceback_with_v(monkeypatch, capsys, material):
    def broken(_args):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(btf_commands, "cmd_info", broken)
    assert main(["info", str(material)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("internal error: ZeroDivisionError")
    assert "rerun with -v" in err
    assert main(["-v", "info", str(material)]) == 1
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and "broken" in err


def test_bad_input_is_one_line_exit_2(tmp_path, capsys):
    assert main(["info", str(tmp_path / "missing.btfm")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "missing.btfm" in err


#: A command that blocks inside the atomic write (after its temporary file exists), so a
#: signal arrives mid-write. The writer is the real one; only the write is slowed.
SLOW_WRITE = """
import sys, time
from btf_addon.cli import btf_commands
from btf_addon.core.fileio import atomic_write
def slow(path, btf):
    def write(fh):
        fh.write(b"partial")
        fh.flush()
        print("writing", flush=True)
        time.sleep(60)
    return atomic_write(path, write)
btf_commands.write_container = slow
from btf_addon.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize(
    ("sig", "word"), [(signal.SIGTERM, "terminated"), (signal.SIGINT, "interrupted")]
)
def test_a_signal_mid_write_exits_130_and_removes_the_temporary(tmp_path, sig, word):
    out = tmp_path / "out" / "m.btfm"
    proc = subprocess.Popen(
        [sys.executable, "-c", SLOW_WRITE, "synth", "lambertian", "-o", str(out)],
        cwd=ROOT,
        env=cli_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout.readline().strip() == "writing"
        assert any(p.name.endswith(".tmp.btfm") for p in out.parent.iterdir())
        proc.send_signal(sig)
        _stdout, stderr = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 130, stderr
    assert word in stderr and "Traceback" not in stderr
    assert list(out.parent.iterdir()) == []  # no output, no temporary


#: F12 whose render callback blocks (after saying so): a signal then arrives inside Blender's
#: engine callback, where Blender catches the exception, reports it and saves the image.
SLOW_F12 = """
import sys, time
from btf_addon.blender import final_render
def slow(engine, depsgraph):
    print("rendering", flush=True)
    time.sleep(120)
final_render.render = slow
from btf_addon.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def test_sigterm_during_f12_exits_130_without_an_image(tmp_path):
    out = tmp_path / "r.png"
    proc = subprocess.Popen(
        [sys.executable, "-c", SLOW_F12, "render", "--demo", "-o", str(out),
         "--resolution", "32x24"],
        cwd=ROOT, env=cli_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        while (line := proc.stdout.readline()) and line.strip() != "rendering":
            pass
        assert line.strip() == "rendering"
        proc.send_signal(signal.SIGTERM)
        _stdout, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, stderr
    assert "terminated" in stderr.strip().splitlines()[-1]
    assert not out.exists()


def test_a_killed_writers_temporary_is_removed_by_the_next_write(tmp_path):
    out = tmp_path / "m.btfm"
    proc = subprocess.Popen(
        [sys.executable, "-c", SLOW_WRITE, "synth", "lambertian", "-o", str(out)],
        cwd=ROOT,
        env=cli_env(),
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline().strip() == "writing"
    proc.send_signal(signal.SIGKILL)  # nothing can clean up after this
    proc.wait(timeout=30)
    left = [p for p in tmp_path.iterdir() if p.name.startswith(f".m.pid{proc.pid}-")]
    assert len(left) == 1
    run_cli("synth", "lambertian", "-o", out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.btfm"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--samples", "-1"], "--samples: must be at least 1"),
        (["--samples", "0"], "--samples: must be at least 1"),
        (["--bounces", "-1"], "--bounces: must be at least 0"),
        (["--seed", "-3"], "--seed: must be at least 0"),
        (["--clamp-indirect", "-1"], "--clamp-indirect: must be a finite number of at least 0"),
        (["--clamp-indirect", "inf"], "--clamp-indirect: must be a finite number of at least 0"),
        (["--clamp-indirect", "x"], "--clamp-indirect: must be a number"),
        (["--samples-per-camera-ray", "0"], "--samples-per-camera-ray: must be at least 1"),
        (["--samples-per-camera-ray", "17"], "--samples-per-camera-ray: must be at most 16"),
        (["--noise-threshold", "-0.1"], "--noise-threshold: must be a finite number of at least 0"),
        (["--noise-threshold", "2"], "--noise-threshold: must be at most 1"),
        (["--noise-threshold", "x"], "--noise-threshold: must be a number"),
    ],
)
def test_render_flags_out_of_range_are_refused_before_blender(tmp_path, args, message):
    proc = run_cli("render", "--demo", "-o", tmp_path / "r.png", *args, check=False)
    assert proc.returncode == 2 and message in proc.stderr


@pytest.mark.parametrize("content", [b"", b"hello, not a blend", b"BLENDER-v500RENDH"])
def test_a_file_that_is_not_a_whole_blend_is_one_line(tmp_path, content):
    """Not a .blend (refused before Blender starts) or truncated (Blender's own words)."""
    blend = tmp_path / "x.blend"
    blend.write_bytes(content)
    proc = run_cli("render", "--blend", blend, "-o", tmp_path / "r.png", check=False)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert str(blend) in proc.stderr.strip().splitlines()[-1]


def _write(path, kind):
    if kind == "empty":
        path.write_bytes(b"")
    elif kind == "npz":
        np.savez(path, q=np.zeros((2, 6)))
    elif kind == "complex":
        np.save(path, np.zeros((2, 6), np.complex64))
    elif kind == "strings":
        np.save(path, np.array([["0"] * 6]))
    elif kind == "object":
        np.save(path, np.array([[None] * 6], dtype=object), allow_pickle=True)
    elif kind == "bool":
        np.save(path, np.zeros((2, 6), bool))
    elif kind == "truncated":
        np.save(path, np.zeros((100, 6), np.float32))
        path.write_bytes(path.read_bytes()[:-10])
    elif kind == "folder":
        path.mkdir()


@pytest.mark.parametrize(
    "kind", ["empty", "npz", "complex", "strings", "object", "bool", "truncated", "folder"]
)
def test_query_files_that_are_not_real_n_by_6_arrays_are_refused(tmp_path, material, kind):
    q = tmp_path / "q.npy"
    _write(q, kind)
    proc = run_cli("eval", material, "--queries", q, "--out", tmp_path / "v.npy", check=False)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and str(q) in proc.stderr
    assert not (tmp_path / "v.npy").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--rotation", "nan"], "--rotation must be a finite number"),
        (["--rotation", "inf"], "--rotation must be a finite number"),
        (["--strength", "nan"], "--strength must be a finite number"),
        (["--strength", "-1"], "--strength must be ≥ 0"),
    ],
)
def test_envmap_refuses_non_finite_parameters(tmp_path, args, message):
    from btf_addon.core.formats.imageio import write_exr

    write_exr(tmp_path / "e.exr", np.ones((4, 8, 3), np.float32))
    proc = run_cli("envmap", tmp_path / "e.exr", *args, "-o", tmp_path / "l.npz", check=False)
    assert proc.returncode == 2 and message in proc.stderr
    assert not (tmp_path / "l.npz").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["lambertian", "--tabulate", "0"], "ring step between"),
        (["lambertian", "--tabulate", "nan"], "ring step between"),
        (["lambertian", "--tabulate", "0.1"], "ring step between"),
        (["woven", "--texels", "0"], "--texels must be at least 1"),
        (["woven", "--relief", "nan"], "--relief must be finite"),
    ],
)
def test_synth_parameters_are_refused_with_a_message(tmp_path, args, message):
    proc = run_cli("synth", *args, "-o", tmp_path / "s.btfm", check=False)
    assert proc.returncode == 2 and message in proc.stderr


def test_outputs_honour_the_umask(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "btf_addon", "synth", "lambertian", "-o", tmp_path / "l.btfm"],
        cwd=ROOT,
        env=cli_env(),
        preexec_fn=lambda: os.umask(0o027),
        check=True,
    )
    assert proc.returncode == 0
    assert (tmp_path / "l.btfm").stat().st_mode & 0o777 == 0o640


def test_tabulating_says_what_it_will_write(tmp_path):
    t0 = time.perf_counter()
    proc = run_cli("synth", "lambertian", "--tabulate", "30", "-o", tmp_path / "t.btfm")
    assert "tabulating" in proc.stderr and "lights" in proc.stderr
    assert time.perf_counter() - t0 < 60


def test_a_blend_saved_at_a_size_that_cannot_fit_is_refused_before_rendering(tmp_path):
    """The size is the file's own (no --resolution): refused once the file is open, before
    F12 starts; 16384² needs about 41 GB by the model, over the 4G stated here."""
    blend = tmp_path / "huge.blend"
    make_blend(
        blend,
        "bpy.ops.object.camera_add()\n"
        "scene.camera = bpy.context.object\n"
        "scene.render.resolution_x = scene.render.resolution_y = 16384\n"
        "scene.render.resolution_percentage = 100\n",
    )
    proc = run_cli(
        "--max-memory", "4G", "render", "--blend", blend, "-o", tmp_path / "r.png", check=False
    )
    assert proc.returncode == 2, proc.stderr
    assert "a 16384x16384 render needs about" in proc.stderr.strip().splitlines()[-1]
    assert not (tmp_path / "r.png").exists()

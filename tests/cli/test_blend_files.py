"""Every command that opens a .blend refuses one it cannot open the same way (issue 30 item 14:
``bridge --blend`` and ``accuracy --blend`` said "internal error" where ``render`` refused):
a file that is no .blend before Blender starts, a damaged one in Blender's words; exit 2, no
traceback, the file named."""

from __future__ import annotations

import pytest
from helpers import run_cli

COMMANDS = {
    "render": lambda blend, out: ["render", "--blend", blend, "-o", out / "x.png"],
    "bridge": lambda blend, out: ["bridge", "--blend", blend, "--frames", "1"],
    "accuracy": lambda blend, out: ["accuracy", "--blend", blend, "-o", out / "report"],
}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_file_that_is_no_blend(tmp_path, command):
    blend = tmp_path / "notes.blend"
    blend.write_text("not a blend file\n")
    proc = run_cli(*COMMANDS[command](blend, tmp_path), check=False)
    assert proc.returncode == 2, proc.stderr
    assert f"error: {blend}: not a .blend file" in proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_damaged_blend(tmp_path, command):
    """It starts as a .blend (the header of Blender 5.0's files) and stops after 64 bytes of
    nothing: Blender itself refuses it."""
    blend = tmp_path / "damaged.blend"
    blend.write_bytes(b"BLENDER17-01v0500" + bytes(64))
    proc = run_cli(*COMMANDS[command](blend, tmp_path), check=False)
    assert proc.returncode == 2, proc.stderr
    assert f"error: {blend}: Blender cannot open it" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr

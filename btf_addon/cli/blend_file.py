"""The one way a command starts Blender and opens a .blend (``render``, ``bridge``,
``accuracy``): Blender imported with interrupts held until its start-up is done, a file that
cannot be a .blend refused before Blender starts, and one Blender cannot read (truncated,
damaged) a clear error naming it, in Blender's words, never an internal error."""

from __future__ import annotations

from pathlib import Path

from ..core.errors import BTFError

#: How a .blend starts: plain, gzip-compressed (Blender < 3.0) or zstd-compressed (3.0+).
BLEND_MAGICS = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")


def import_bpy(purpose: str):
    """Blender's module, imported whole: a Ctrl-C or SIGTERM during its start-up waits until
    the start-up is done (a half-started Blender segfaulted on exit), then stops the command."""
    from .main import signals_held

    with signals_held():
        try:
            import bpy
        except ImportError:
            raise BTFError(
                f"{purpose} needs Blender's bpy module (pip install bpy==5.0.1)"
            ) from None
    return bpy


def check_blend(path: Path) -> None:
    """A file that cannot be a .blend is refused before Blender starts (Blender would print
    its own error and the command would fail with a traceback)."""
    if not path.is_file():
        raise BTFError(f"{path}: no such .blend file")
    with open(path, "rb") as fh:
        head = fh.read(8)
    if not head.startswith(BLEND_MAGICS):
        raise BTFError(f"{path}: not a .blend file (it does not start as one)")


def open_blend(bpy, path: Path) -> None:
    """``check_blend``, then open ``path`` in Blender; BTFError when Blender cannot read it."""
    check_blend(path)
    try:
        bpy.ops.wm.open_mainfile(filepath=str(path.resolve()))
    except RuntimeError as exc:  # truncated or damaged: Blender's own words
        raise BTFError(f"{path}: Blender cannot open it ({report_text(str(exc))})") from None


def report_text(text: str) -> str:
    """Blender's "Error: …" reports, each once (an engine both sets a render's error and
    reports it; a failed open reports per problem)."""
    reports = [r.strip() for r in text.split("Error: ") if r.strip()]
    return "\n".join(dict.fromkeys(reports))

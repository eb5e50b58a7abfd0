"""One bake of an evaluated scene, whoever asks (the CLI's ``bake``, the Bake Light for VR
operator): the scene exported as F12 exports it, its render settings' bounces and Clamp
Indirect, the bake's own knobs, and the bake and its report written beside the .blend the same
way, so two callers with the same file and knobs write the same data.

Re-baking: the bake already at the output path (``last_bake``) is what a new bake keeps the
unchanged objects' values from (cl/bake.py ``bake_scene``'s ``previous``: only what is stale or
missing is traced); a file that does not load is not used, and the caller says why in one
line. Asked to bake everything, the file is not read at all.

Export (``export_for_bake``) needs bpy and runs on the main thread; reading the last bake
(``last_bake``), the bake (``bake_exported``) and the writing (``write_bake``) touch no bpy data
and may run on a worker thread."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

from ...cl.bake import BakeKnobs, bake_scene
from ...cl.context import create_context
from ...core.fileio import atomic_write
from ...render.light_bake import LightBake, LightBakeError, load
from ...scene.scene import Scene
from ..export import export_scene
from ..sync import frame_size, render_settings


def report_path(bake_path: str | Path) -> Path:
    """The report beside the bake: ``….light_bake.json``."""
    path = Path(bake_path)
    return path.with_name(path.name[: -len(".npz")] + ".json")


def knobs_for(scene, spacing: float, view_bins: int, samples: int) -> BakeKnobs:
    """The bake's knobs with the scene's Sampled-mode bounces, Clamp Indirect and seed."""
    settings = render_settings(scene)
    return BakeKnobs(
        spacing=spacing,
        view_bins=view_bins,
        samples=samples,
        bounces=settings.max_bounces,
        clamp_indirect=settings.clamp_indirect,
        seed=settings.seed,
    )


def export_for_bake(depsgraph) -> Scene:
    """The evaluated scene as F12 exports it (main thread)."""
    return export_scene(depsgraph, *frame_size(depsgraph.scene.render), light_bake=False)


def last_bake(path: str | Path, everything: bool = False) -> tuple[LightBake | None, str]:
    """The bake at ``path`` to keep unchanged objects from, and "" — or None and why not in one
    line ("" too where there is no file yet or ``everything`` is asked for: nothing to say)."""
    if everything or not Path(path).is_file():
        return None, ""
    try:
        return load(path), ""
    except LightBakeError as exc:
        return None, f"baking everything: the last bake is not used ({exc})"


def bake_exported(
    exported: Scene,
    knobs: BakeKnobs,
    device_index: int | None = None,
    progress: Callable[[float], bool] | None = None,
    previous: LightBake | None = None,
) -> LightBake:
    """The exported scene baked on the chosen device (any thread); with ``previous``, only
    what is stale or missing there is traced (cl/bake.py ``bake_scene``), and the device is
    opened only then."""
    return bake_scene(exported, lambda: create_context(device_index), knobs, progress, previous)


def kept_summary(bake: LightBake) -> str:
    """One line naming the objects kept from the last bake; "" where none was."""
    kept = [m.name for m in bake.meshes if m.kept]
    if not kept:
        return ""
    traced = sum(m.baked and not m.kept for m in bake.meshes)
    names = ", ".join(f"'{name}'" for name in kept)
    return (
        f"kept unchanged since the last bake: {names}; "
        f"{traced} object{'s' if traced != 1 else ''} baked again"
    )


def write_bake(bake: LightBake, path: str | Path) -> Path:
    """The bake and its JSON report, each written whole; returns the report's path."""
    bake.save(path)
    report = report_path(path)
    text = json.dumps(bake.report(), indent=2).encode()
    atomic_write(report, lambda f: f.write(text))
    return report

"""File > Import > BTF Material: load a BTF, create a material for it, assign it to the selection.

Loading validates the whole BTF (BTFbase text tables take about a second) in a worker thread
while a modal operator shows progress and honours Esc; nothing in the .blend changes until the
BTF has loaded and passed every check, so a cancelled or failed import leaves no trace. The
material is created in one step that Blender's undo records (bl_options UNDO). In background
mode (no window to run a modal loop in) the same steps run synchronously.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import NamedTuple

import bpy
import numpy as np
from bpy.props import BoolProperty, StringProperty
from bpy.types import Operator
from bpy_extras.io_utils import ImportHelper

from ..core.codecs import load_btf
from ..core.errors import BTFError
from ..core.model import BTF
from ..core.packed import pack
from .export.meshes import GEOMETRY_OBJECT_TYPES


class LoadJob:
    """Loads and checks a BTF in a daemon thread. ``cancel`` only marks the result unwanted:
    the loader cannot be interrupted, but nothing is done with what it returns."""

    def __init__(self, path: Path):
        self.path, self.btf, self.error = path, None, None
        self._thread = threading.Thread(target=self._run, daemon=True, name="btf-import")

    def _run(self) -> None:
        try:
            btf = load_btf(self.path)
            pack(btf)  # the GPU back ends must be able to draw it: refuse now, not at F12
            self.btf = btf
        except (BTFError, OSError, ValueError) as exc:
            self.error = str(exc)

    def start(self) -> LoadJob:
        self._thread.start()
        return self

    def wait(self, timeout: float | None = None) -> bool:
        self._thread.join(timeout)
        return not self._thread.is_alive()


def btf_source(filepath: str) -> Path:
    """A .btfm, UBO2014 .btf or image-set .zip is the source itself; any other file inside a
    material folder (BTFbase tables or binary.btf, an image set's images) stands for the folder."""
    path = Path(filepath)
    if path.is_dir() or path.suffix.lower() in (".btfm", ".zip"):
        return path
    if path.suffix.lower() == ".btf" and path.name != "binary.btf":  # UBO2014; binary.btf
        return path  # stands for its BTFbase folder, which then picks text or binary
    return path.parent  # a table or image of a folder (BTFbase, UBO2003/ATRIUM image set)


def display_colour(btf: BTF) -> tuple[float, float, float, float]:
    """The BTF's mean reflectance at normal incidence: what Solid view and other engines show."""
    g = (np.arange(8) + 0.5) / 8
    uv = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    z = np.tile([0.0, 0.0, 1.0], (len(uv), 1))
    rgb = np.clip(btf.evaluate(uv, z, z).mean(axis=0) * np.pi, 0.0, 1.0)
    return (*map(float, rgb), 1.0)


class CreatedMaterial(NamedTuple):
    material: bpy.types.Material
    assigned: int  # how many of the objects it was assigned to


def create_material(name: str, source: str, btf: BTF, objects) -> CreatedMaterial:
    """A new BTF material, assigned to those of ``objects`` that can hold one (into the active
    slot, or a new slot where an object has none)."""
    material = bpy.data.materials.new(name)
    material.btf.enabled = True
    material.btf.source = source
    material.diffuse_color = display_colour(btf)
    if material.node_tree is not None:  # other engines show the mean colour
        principled = material.node_tree.nodes.get("Principled BSDF")
        if principled is not None:
            principled.inputs["Base Color"].default_value = material.diffuse_color
    assigned = 0
    for obj in objects:
        if obj.type not in GEOMETRY_OBJECT_TYPES:
            continue
        if len(obj.material_slots) == 0:
            obj.data.materials.append(material)
        else:
            obj.material_slots[obj.active_material_index].material = material
        assigned += 1
    return CreatedMaterial(material, assigned)


class BTF_OT_import_material(Operator, ImportHelper):
    """Load a BTF (a .btfm file, or any file of a BTFbase material folder), create a BTF
    material from it and assign it to the selected objects"""

    bl_idname = "btf.import_material"
    bl_label = "Import BTF Material"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(
        default="*.btfm;*.txt;*.dat;*.btf;*.zip;*.jpg;*.hdr", options={"HIDDEN"}
    )
    relative_path: BoolProperty(
        name="Relative Path",
        default=True,
        description="Store the path relative to the .blend file, so other machines find it",
    )

    _job: LoadJob | None = None
    _timer = None
    _ticks = 0

    def _source_path(self, source: Path) -> str:
        if self.relative_path and bpy.data.filepath:
            try:
                return bpy.path.relpath(str(source))
            except ValueError:  # another drive on Windows: no relative path exists
                pass
        return str(source)

    def _finish(self, context, job: LoadJob) -> set[str]:
        if job.error is not None:
            self.report({"ERROR"}, f"BTF import failed: {job.error}")
            return {"CANCELLED"}
        source = btf_source(self.filepath)
        selected = list(context.selected_objects) if hasattr(context, "selected_objects") else []
        material, assigned = create_material(
            source.stem if source.suffix else source.name,
            self._source_path(source),
            job.btf,
            selected,
        )
        self.report({"INFO"}, f"created material {material.name!r}, assigned to {assigned} objects")
        return {"FINISHED"}

    def execute(self, context):
        source = btf_source(self.filepath)
        if not os.path.exists(source):
            self.report({"ERROR"}, f"{source}: no such file or folder")
            return {"CANCELLED"}
        job = LoadJob(source).start()
        window = getattr(context, "window", None)
        if window is None or bpy.app.background:
            job.wait()
            return self._finish(context, job)
        self._job = job
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        self.report({"INFO"}, f"loading {source.name}… (Esc cancels)")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        wm = context.window_manager
        if event.type == "ESC":
            self._end(context)
            self.report({"WARNING"}, "BTF import cancelled; nothing was changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if not self._job.wait(0.0):
            # The loader reports no fraction; the bar shows that work goes on.
            self._ticks += 1
            wm.progress_update((5 * self._ticks) % 100)
            return {"RUNNING_MODAL"}
        self._end(context)
        return self._finish(context, self._job)

    def _end(self, context) -> None:
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()


def menu_import(self, context) -> None:
    self.layout.operator(BTF_OT_import_material.bl_idname, text="BTF Material")


classes = (BTF_OT_import_material,)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register() -> None:
    _register()
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister() -> None:
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    _unregister()

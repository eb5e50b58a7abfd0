"""File > Import > BTF Material: load a BTF, create a material for it, assign it to the selection
(or, from the material's BTF panel, fill that material: nothing is orphaned).

Loading validates the whole BTF (BTFbase text tables take about a second) in a worker thread
while a modal operator shows progress and honours Esc; nothing in the .blend changes until the
BTF has loaded and passed every check, so a cancelled or failed import leaves no trace. The
material is created in one step that Blender's undo records (bl_options UNDO). In background
mode (no window to run a modal loop in) the same steps run synchronously.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import NamedTuple

import bpy
import numpy as np
from bpy.props import BoolProperty, FloatProperty, StringProperty
from bpy.types import Operator
from bpy_extras.io_utils import ImportHelper

from ...core.codecs.packed import pack
from ...core.errors import BTFError
from ...core.formats.load import load_btf
from ...core.model import BTF
from ..export.meshes import GEOMETRY_OBJECT_TYPES
from ..paths import source_for, source_hint


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
    """A .btfm file or a folder is the source itself; any other file inside a BTFbase material
    folder (its text tables, ``binary.btf``) stands for the folder (paths.source_for)."""
    return Path(source_for(filepath))


def display_colour(btf: BTF) -> tuple[float, float, float, float]:
    """The BTF's mean reflectance at normal incidence: what Solid view and other engines show."""
    g = (np.arange(8) + 0.5) / 8
    uv = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    z = np.tile([0.0, 0.0, 1.0], (len(uv), 1))
    rgb = np.clip(btf.evaluate(uv, z, z).mean(axis=0) * np.pi, 0.0, 1.0)
    return (*map(float, rgb), 1.0)


def fill_material(material, source: str, btf: BTF) -> None:
    """Make ``material`` render ``btf`` from ``source`` (its other settings kept), with the
    BTF's mean colour for Solid view and other engines."""
    material.btf.enabled = True
    material.btf.source = source
    material.diffuse_color = display_colour(btf)
    if material.node_tree is not None:  # other engines show the mean colour
        principled = material.node_tree.nodes.get("Principled BSDF")
        if principled is not None:
            principled.inputs["Base Color"].default_value = material.diffuse_color


#: Texel size assumed when a BTF does not state its physical size (BTFbase's tables do not):
#: 0.1 mm (≈ 250 DPI) is a middle-of-the-road guess for measured BTFs; the import dialog
#: shows it, the material stores it, the Mapping panel says it came from the import.
DEFAULT_TEXEL_MM = 0.1


def place_on(material, btf: BTF, objects, texel_mm: float = DEFAULT_TEXEL_MM) -> None:
    """Mapping defaults for a new import (issue 20): UV with real-world size where every
    target mesh has a UV map, else Box in object space; a tile size from ``texel_mm`` per
    texel where the BTF states none (stored on the material)."""
    settings = material.btf
    targets = [o for o in objects if o.type in GEOMETRY_OBJECT_TYPES]
    unwrapped = all(o.type == "MESH" and len(o.data.uv_layers) > 0 for o in targets)
    settings.mapping = "UV" if targets and unwrapped else "BOX"
    settings.box_space = "OBJECT"
    settings.use_real_world_size = True
    settings.texel_filter = "LINEAR"
    if btf.meta.tile_size_mm is None:
        settings.tile_size_mm = (texel_mm * btf.meta.width, texel_mm * btf.meta.height)
        settings.tile_size_origin = "ASSUMED"  # after the edit, which marks it as the user's
        settings.assumed_texel_mm = texel_mm


class CreatedMaterial(NamedTuple):
    material: bpy.types.Material
    assigned: int  # how many of the objects it was assigned to


def create_material(name: str, source: str, btf: BTF, objects) -> CreatedMaterial:
    """A new BTF material, assigned to those of ``objects`` that can hold one (into the active
    slot, or a new slot where an object has none)."""
    material = bpy.data.materials.new(name)
    fill_material(material, source, btf)
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

    # SKIP_SAVE: a file dropped on the window (file_handler.py) runs at once; the menu entry
    # must still open the browser, not reuse the last path.
    filepath: StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE"})
    filter_glob: StringProperty(
        default="*.btfm;*.txt;*.dat;*.btf;*.zip;*.jpg;*.hdr", options={"HIDDEN"}
    )
    target_material: StringProperty(
        name="Material",
        default="",
        options={"HIDDEN", "SKIP_SAVE"},
        description="Fill this material with the BTF instead of creating a new one",
    )
    relative_path: BoolProperty(
        name="Relative Path",
        default=True,
        description="Store the path relative to the .blend file, so other machines find it",
    )
    texel_size_mm: FloatProperty(
        name="Texel Size (mm)",
        default=DEFAULT_TEXEL_MM,
        min=1e-4,
        soft_max=10.0,
        precision=3,
        description="Physical size of one texel, used only when the BTF does not state its "
        "size (BTFbase materials do not; UBO2014 files do). The tile is this × its texels; "
        "change it later in the material's Mapping panel",
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
        target = bpy.data.materials.get(self.target_material) if self.target_material else None
        if target is not None:
            fill_material(target, self._source_path(source), job.btf)
            users = [
                o for o in bpy.data.objects if any(m.material == target for m in o.material_slots)
            ]
            place_on(target, job.btf, users, self.texel_size_mm)
            self.report({"INFO"}, f"material {target.name!r} now renders {source.name}")
            return {"FINISHED"}
        selected = list(context.selected_objects) if hasattr(context, "selected_objects") else []
        material, assigned = create_material(
            source.stem if source.suffix else source.name,
            self._source_path(source),
            job.btf,
            selected,
        )
        place_on(material, job.btf, selected, self.texel_size_mm)
        self.report({"INFO"}, f"created material {material.name!r}, assigned to {assigned} objects")
        return {"FINISHED"}

    def invoke(self, context, event):
        if self.filepath:  # dropped on the window (file_handler.py): no browser
            return self.execute(context)
        return super().invoke(context, event)

    def execute(self, context):
        if self.target_material and self.target_material not in bpy.data.materials:
            self.report({"ERROR"}, f"no material {self.target_material!r} to fill")
            return {"CANCELLED"}
        hint = source_hint(self.filepath)
        if hint:
            self.report({"ERROR"}, hint)
            return {"CANCELLED"}
        source = btf_source(self.filepath)
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

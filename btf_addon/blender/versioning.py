"""Old files keep their look when defaults change: a settings version stored in the file.

Blender stores an add-on property only once it has been set; an untouched one reads back as
whatever default the running code declares. So when a default changes (a new F12 mode, texel
filtering, real-world mapping), an old file would silently render differently. Each scene
carries ``btf_settings_version`` (stamped on every save); on load, a file older than
``SETTINGS_VERSION`` gets, for every property whose default changed since its version and that
it never set (``is_property_set``), the default it was made with, written explicitly. A farm
re-rendering an old file then matches the frames rendered before.

To change a default: bump ``SETTINGS_VERSION`` and add one ``Upgrade`` row per changed
property, with the version that changed it and the old value. Renaming an enum identifier needs
no row as long as its number stays (Blender stores enum values by number; render_settings.py
numbers them from the Python enums' values).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import bpy
from bpy.app.handlers import persistent
from bpy.props import IntProperty

#: The settings version this code writes. 0: files saved before versioning (issue 14); 2: the
#: VR session and the XTAL bridge share their settings' defaults (vr/headset_settings.py); 3: the
#: Sampled F12 clamps indirect light by default (issue 33); 4: its samples share camera rays,
#: 4 to a ray, by default (issue 33); 5: it samples adaptively by default (issue 33).
SETTINGS_VERSION = 5


class Upgrade(NamedTuple):
    """``owner`` ('scene' or 'material') · ``group`` (its property group attribute) ·
    ``prop``: a property whose default changed in ``version`` from ``old``."""

    version: int
    owner: str
    group: str
    prop: str
    old: Any


UPGRADES = (
    Upgrade(1, "scene", "btf_render", "final_mode", "VIRTUAL"),
    Upgrade(1, "scene", "btf_render", "use_antialiasing", False),
    Upgrade(1, "material", "btf", "texel_filter", "NEAREST"),
    Upgrade(1, "material", "btf", "mapping", "UV"),
    Upgrade(1, "material", "btf", "use_real_world_size", False),
    # Now 0, "the headset's display period", as the bridge's; the VR session holds 11 ms for it
    # all the same (it is never told the period), so this keeps what the panel showed.
    Upgrade(2, "scene", "btf_vr", "frame_budget_ms", 11.0),
    # Files made before the clamp render unbiased, as they did.
    Upgrade(3, "scene", "btf_render", "clamp_indirect", 0.0),
    # ... and trace a camera ray per sample, as they did.
    Upgrade(4, "scene", "btf_render", "samples_per_camera_ray", 1),
    # ... and give every pixel every sample, as they did.
    Upgrade(5, "scene", "btf_render", "use_adaptive_sampling", False),
)


def file_version() -> int:
    """The settings version of the open file: the oldest of its scenes (all are stamped
    together on save; a scene appended from an older file keeps its own)."""
    scenes = [s for s in bpy.data.scenes if s.library is None]
    return min((s.btf_settings_version for s in scenes), default=SETTINGS_VERSION)


def _owners(owner: str):
    blocks = bpy.data.scenes if owner == "scene" else bpy.data.materials
    return [b for b in blocks if b.library is None]  # linked data cannot be written


def upgrade(version: int) -> list[str]:
    """Give every property whose default changed after ``version`` its old default where the
    file never set it. Rows whose property this code lacks are skipped. Returns what was set,
    as 'block.group.prop = value' lines."""
    done = []
    for row in UPGRADES:
        if row.version <= version:
            continue
        for block in _owners(row.owner):
            group = getattr(block, row.group, None)
            if group is None or row.prop not in group.bl_rna.properties:
                continue
            if group.is_property_set(row.prop):
                continue
            setattr(group, row.prop, row.old)
            done.append(f"{block.name}.{row.group}.{row.prop} = {row.old!r}")
    return done


def stamp() -> None:
    for scene in _owners("scene"):
        scene.btf_settings_version = SETTINGS_VERSION


@persistent
def upgrade_on_load(filepath: str = "", *_args) -> None:
    """load_post: upgrade a saved file (the startup file, with no path, is new: current
    defaults are its defaults). The version itself is stamped on save only, so opening an
    up-to-date file leaves it unmodified."""
    upgraded.clear()
    if not bpy.data.filepath:
        return
    version = file_version()
    if version < SETTINGS_VERSION:
        done = upgrade(version)
        if done:
            upgraded.extend(done)
            _report(
                f"BTF: {bpy.data.filepath} has settings version {version}; kept its look by "
                f"setting the old defaults: {'; '.join(done)}"
            )


#: What the last file load upgraded ('block.group.prop = value'), shown by the render panel
#: until another file is loaded.
upgraded: list[str] = []


def _report(message: str) -> None:
    """Into Blender's reports (the status bar and Info editor; stdout in background) through
    an operator, the only thing that can report. A load_post handler runs before the window is
    ready for them, so with a UI the report waits for the next event loop turn."""
    if bpy.app.background:
        bpy.ops.btf.report_upgrade(message=message)
    else:
        bpy.app.timers.register(lambda: bpy.ops.btf.report_upgrade(message=message) and None)


class BTF_OT_report_upgrade(bpy.types.Operator):
    """Say what opening an older file changed"""

    bl_idname = "btf.report_upgrade"
    bl_label = "Report BTF Settings Upgrade"
    bl_options = {"INTERNAL"}

    message: bpy.props.StringProperty()

    def execute(self, context):
        self.report({"INFO"}, self.message)
        return {"FINISHED"}


@persistent
def stamp_on_save(*_args) -> None:
    stamp()


def register() -> None:
    bpy.types.Scene.btf_settings_version = IntProperty(
        name="BTF Settings Version",
        default=0,
        min=0,
        options={"HIDDEN"},
        description="Version of the BTF settings this file was saved with (upgraded on load)",
    )
    bpy.utils.register_class(BTF_OT_report_upgrade)
    bpy.app.handlers.load_post.append(upgrade_on_load)
    bpy.app.handlers.save_pre.append(stamp_on_save)


def unregister() -> None:
    bpy.app.handlers.save_pre.remove(stamp_on_save)
    bpy.app.handlers.load_post.remove(upgrade_on_load)
    bpy.utils.unregister_class(BTF_OT_report_upgrade)
    del bpy.types.Scene.btf_settings_version

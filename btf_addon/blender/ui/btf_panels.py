"""Panels."""

from __future__ import annotations

import os

import bpy
from bpy.types import Panel

from ...render.settings import FinalMode, Lighting, RenderSettings
from .. import versioning
from ..addon import ENGINE_ID
from ..export.materials import known_problem, load_notes


class BTF_PT_material(Panel):
    bl_label = "BTF"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"

    @classmethod
    def poll(cls, context) -> bool:
        # Only under this engine: Cycles and EEVEE render the material's nodes, not its BTF.
        return context.engine == ENGINE_ID and context.material is not None

    def draw_header(self, context) -> None:
        self.layout.prop(context.material.btf, "enabled", text="")

    def draw(self, context) -> None:
        settings = context.material.btf
        layout = self.layout
        layout.use_property_split = True
        # Fills this material (no new material, nothing orphaned).
        op = layout.operator("btf.import_material", text="Load BTF…", icon="IMPORT")
        op.target_material = context.material.name
        col = layout.column()
        col.active = settings.enabled
        col.prop(settings, "source")
        if _is_folder(settings.source):  # a BTFbase folder: text tables or binary.btf
            col.prop(settings, "prefer_binary")
        if settings.enabled:
            # What F12 would report, before an F12: the path is gone, or its last load failed
            # or warned (a damaged text table read from binary.btf).
            problem = known_problem(settings.source)
            if problem:
                layout.label(text=problem, icon="ERROR")
            for note in load_notes(settings.source, settings.prefer_binary):
                layout.label(text=note, icon="ERROR")
        col.prop(settings, "exposure")


def _is_folder(source: str) -> bool:
    return bool(source) and os.path.isdir(bpy.path.abspath(source))


class BTF_PT_render_settings(Panel):
    bl_label = "BTF"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    @classmethod
    def poll(cls, context) -> bool:
        return context.engine == ENGINE_ID

    def draw(self, context) -> None:
        settings = context.scene.btf_render
        values = RenderSettings.from_properties(settings)
        layout = self.layout
        layout.use_property_split = True
        layout.prop(settings, "lighting")
        col = layout.column()
        col.active = values.lighting is Lighting.ENVIRONMENT
        col.prop(settings, "lights_total")
        col.prop(settings, "seed")
        layout.prop(settings, "progressive")
        row = layout.row()
        row.active = values.progressive
        row.prop(settings, "lights_per_redraw")
        layout.prop(settings, "final_mode")
        col = layout.column()
        col.active = values.final_mode is FinalMode.SAMPLED
        col.prop(settings, "samples")
        row = col.row(heading="Noise Threshold")
        row.prop(settings, "use_adaptive_sampling", text="")
        sub = row.row()
        sub.active = values.use_adaptive_sampling
        sub.prop(settings, "adaptive_threshold", text="")
        row = col.row()
        row.active = values.use_antialiasing
        row.prop(settings, "samples_per_camera_ray")
        col.prop(settings, "max_bounces")
        col.prop(settings, "clamp_indirect")
        col.prop(settings, "btf_importance_sampling")
        layout.prop(settings, "fixed_launch_split")
        draw_device(layout)
        if versioning.upgraded:  # the file was saved by an older version: say what it kept
            box = layout.box()
            box.label(text="Opened from an older version; kept its look by setting:", icon="INFO")
            for line in versioning.upgraded:
                box.label(text=line)


def draw_device(layout) -> None:
    """Which device F12 renders on: the preferences' choice where it builds programs, else the
    first that does (cl/devices.py), and what the last render actually used."""
    from .. import final_render, preferences

    items = preferences.device_items()  # cached: OpenCL is probed once per session
    chosen = preferences.device_identifier(preferences.preferred_device())
    names = {ident: name for ident, name, _d, _n in items}
    default = [n.removesuffix(" — default") for n in names.values() if n.endswith(" — default")]
    label = default[0] if default else None
    picked = names.get(chosen, "")
    if chosen != preferences.AUTOMATIC and picked and not picked.endswith(" — cannot build"):
        label = picked.removesuffix(" — default")
    box = layout.box()
    col = box.column(align=True)
    if label is not None:
        col.label(text=f"F12 device: {label}", icon="SYSTEM")
        if picked.endswith(" — cannot build"):
            col.label(text="The chosen device cannot build programs", icon="ERROR")
    else:
        col.label(text="F12 device: none builds (GLSL fallback, no shadows)", icon="ERROR")
        col.operator("btf.check_system", icon="SYSTEM")
    if final_render.last_device:
        col.label(text=f"Last render: {final_render.last_device}")


classes = (BTF_PT_material, BTF_PT_render_settings)
register, unregister = bpy.utils.register_classes_factory(classes)

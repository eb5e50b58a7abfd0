"""Panels."""

from __future__ import annotations

import bpy
from bpy.types import Panel

from ..render.settings import FinalMode, Lighting, RenderSettings
from .addon import ENGINE_ID


class BTF_PT_material(Panel):
    bl_label = "BTF"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"

    @classmethod
    def poll(cls, context) -> bool:
        return context.material is not None

    def draw_header(self, context) -> None:
        self.layout.prop(context.material.btf, "enabled", text="")

    def draw(self, context) -> None:
        settings = context.material.btf
        layout = self.layout
        layout.use_property_split = True
        layout.operator("btf.import_material", text="Import BTF…", icon="IMPORT")
        col = layout.column()
        col.active = settings.enabled
        col.prop(settings, "source")
        col.prop(settings, "uv_map")
        col.prop(settings, "uv_scale")
        col.prop(settings, "uv_rotation")
        col.prop(settings, "exposure")


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
        col.prop(settings, "max_bounces")


classes = (BTF_PT_material, BTF_PT_render_settings)
register, unregister = bpy.utils.register_classes_factory(classes)

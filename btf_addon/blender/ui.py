"""Panels."""

from __future__ import annotations

import bpy
from bpy.types import Panel


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
        layout.active = settings.enabled
        layout.prop(settings, "source")
        layout.prop(settings, "uv_map")
        layout.prop(settings, "tile_size_mm")
        layout.prop(settings, "uv_scale")
        layout.prop(settings, "uv_rotation")
        layout.prop(settings, "exposure")


classes = (BTF_PT_material,)
register, unregister = bpy.utils.register_classes_factory(classes)

"""Our Film panel: Transparent, and the pixel filter F12 and the viewport's jitter follow.

The filter is the scene's, as Cycles keeps it (``scene.cycles.pixel_filter_type`` and
``filter_width``), so switching the engine between BTF and Cycles keeps one film. Without the
Cycles add-on there is no such property: the panel says that Blender's default,
Blackman-Harris 1.5 px, is used (render/settings.py ``RenderSettings.from_scene``).
"""

from __future__ import annotations

import bpy
from bpy.types import Panel

from ...render.settings import FinalMode, RenderSettings
from ..addon import ENGINE_ID


class BTF_PT_film(Panel):
    bl_label = "BTF Film"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context) -> bool:
        return context.engine == ENGINE_ID

    def draw_header(self, context) -> None:
        self.layout.prop(context.scene.btf_render, "use_antialiasing", text="")

    def draw(self, context) -> None:
        scene = context.scene
        settings = scene.btf_render
        layout = self.layout
        layout.use_property_split = True
        # F12 honours it (alpha 0 where the camera sees the World); Cycles draws it in its own
        # Film panel, which this engine does not show.
        layout.prop(scene.render, "film_transparent", text="Transparent")
        col = layout.column()
        col.active = settings.use_antialiasing
        cycles = getattr(scene, "cycles", None)
        if cycles is not None and hasattr(cycles, "pixel_filter_type"):
            col.prop(cycles, "pixel_filter_type", text="Pixel Filter")
            col.prop(cycles, "filter_width", text="Width")
        else:
            defaults = RenderSettings()
            col.label(
                text=f"Pixel filter: Blackman-Harris {defaults.filter_width:g} px "
                "(Blender's default; enable Cycles to change it)",
                icon="INFO",
            )
        row = col.row()
        row.active = RenderSettings.from_properties(settings).final_mode is FinalMode.VIRTUAL
        row.prop(settings, "aa_samples")
        if not settings.use_antialiasing:
            layout.label(text="Every ray through the pixel centre: edges and fine patterns alias")


classes = (BTF_PT_film,)
register, unregister = bpy.utils.register_classes_factory(classes)

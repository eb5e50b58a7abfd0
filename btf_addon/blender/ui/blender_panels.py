"""Blender's own panels under this engine, by what it honours.

Light, World, Material and View Layer show exactly the data the BTF engine reads
(``export/lights.py``, ``export/world.py``, ``export/materials.py``, the passes F12 writes);
what it ignores is not shown. Blender's panels that draw only such data (the material slot list,
the material preview, ID templates) get this engine in their ``COMPAT_ENGINES``; where Blender's
panel is another engine's view of the data (EEVEE's light with shadows and influence, Cycles'
world with ray visibility), this module has its own, polled by engine.
"""

from __future__ import annotations

import bpy
from bpy.types import Panel

from ..addon import ENGINE_ID

#: Blender's panels shown for this engine as they are (their COMPAT_ENGINES gain ENGINE_ID):
#: they show only data this engine honours.
BLENDER_PANELS = (
    "EEVEE_MATERIAL_PT_context_material",  # slot list, New / Browse
    "MATERIAL_PT_preview",  # rendered through this engine (bl_use_preview)
)


class EnginePanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    COMPAT_ENGINES = {ENGINE_ID}

    @classmethod
    def poll(cls, context) -> bool:
        return context.engine == ENGINE_ID


def draw_node_input(layout, ntree, output_kinds: tuple[str, ...], socket: str) -> None:
    """The node tree feeding ``socket`` of the active output node, as Cycles' Surface panel."""
    node = None
    for kind in output_kinds:
        node = ntree.get_output_node(kind)
        if node is not None:
            break
    if node is None:
        layout.label(text="No output node")
        return
    node_input = node.inputs.get(socket)
    if node_input is None:
        layout.label(text="Incompatible output node")
        return
    layout.template_node_view(ntree, node, node_input)


class BTF_LIGHT_PT_light(EnginePanel, Panel):
    """What export/lights.py reads: colour × power (sun: strength), point/spot radius, spot
    size and blend, area shape and size. Shadows are always traced in F12."""

    bl_label = "Light"
    bl_context = "data"

    @classmethod
    def poll(cls, context) -> bool:
        return super().poll(context) and context.light is not None

    def draw(self, context) -> None:
        light = context.light
        layout = self.layout
        layout.row().prop(light, "type", expand=True)
        layout.use_property_split = True
        col = layout.column()
        col.prop(light, "color")
        col.prop(light, "energy", text="Strength" if light.type == "SUN" else "Power")
        if hasattr(light, "exposure"):
            col.prop(light, "exposure")
        if light.type in {"POINT", "SPOT"}:
            col.prop(light, "shadow_soft_size", text="Radius")
        if light.type == "SPOT":
            col.separator()
            col.prop(light, "spot_size", text="Spot Size")
            col.prop(light, "spot_blend", text="Blend")
        if light.type == "AREA":
            col.separator()
            col.prop(light, "shape")
            sub = col.column(align=True)
            if light.shape in {"SQUARE", "DISK"}:
                sub.prop(light, "size")
            else:
                sub.prop(light, "size", text="Size X")
                sub.prop(light, "size_y", text="Y")


class BTF_WORLD_PT_surface(EnginePanel, Panel):
    """The World's node tree (Background ← Environment Texture ← Mapping: export/world.py)."""

    bl_label = "Surface"
    bl_context = "world"

    @classmethod
    def poll(cls, context) -> bool:
        return super().poll(context) and context.world is not None

    def draw(self, context) -> None:
        world = context.world
        layout = self.layout
        layout.use_property_split = True
        if world.node_tree is None:
            layout.prop(world, "color")
            return
        draw_node_input(layout, world.node_tree, ("CYCLES", "ALL", "EEVEE"), "Surface")
        layout.label(
            text="Read: Background (colour or Environment Texture, strength), Mapping Z rotation",
            icon="INFO",
        )


class BTF_MATERIAL_PT_surface(EnginePanel, Panel):
    """A material without a BTF renders with an analytic BTF of its surface shader
    (export/surface_shaders.py: Diffuse, Glossy, Principled): its node inputs, as Cycles'."""

    bl_label = "Surface"
    bl_context = "material"

    @classmethod
    def poll(cls, context) -> bool:
        material = context.material
        return super().poll(context) and material is not None and not material.btf.enabled

    def draw(self, context) -> None:
        material = context.material
        layout = self.layout
        layout.use_property_split = True
        if material.node_tree is None:
            layout.prop(material, "diffuse_color", text="Base Color")
            return
        draw_node_input(layout, material.node_tree, ("CYCLES", "ALL", "EEVEE"), "Surface")


class BTF_VIEWLAYER_PT_passes(EnginePanel, Panel):
    """The passes F12 writes (registered in engine.update_render_passes)."""

    bl_label = "Passes"
    bl_context = "view_layer"

    def draw(self, context) -> None:
        view_layer = context.view_layer
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column(heading="Include", align=True)
        col.prop(view_layer, "use_pass_combined")
        col.prop(view_layer, "use_pass_z")
        col.prop(view_layer, "use_pass_normal")
        col.prop(view_layer, "use_pass_uv")
        layout.label(text="Depth, Normal and UV need OpenCL (empty in the GLSL fallback)")


def blender_panels():
    for name in BLENDER_PANELS:
        panel = getattr(bpy.types, name, None)
        if panel is not None and getattr(panel, "COMPAT_ENGINES", None) is not None:
            yield panel


classes = (
    BTF_LIGHT_PT_light,
    BTF_WORLD_PT_surface,
    BTF_MATERIAL_PT_surface,
    BTF_VIEWLAYER_PT_passes,
)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register() -> None:
    _register()
    for panel in blender_panels():
        panel.COMPAT_ENGINES.add(ENGINE_ID)


def unregister() -> None:
    for panel in blender_panels():
        panel.COMPAT_ENGINES.discard(ENGINE_ID)
    _unregister()

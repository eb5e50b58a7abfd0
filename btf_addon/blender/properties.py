"""BTF settings stored on each material: ``material.btf``."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, FloatProperty, PointerProperty, StringProperty
from bpy.types import PropertyGroup

from . import compat


def _tag_material(settings, _context) -> None:
    """Blender does not tag the material for re-evaluation when an add-on's property changes
    from Python (a script, a driver-less edit): without this, the depsgraph's evaluated copy —
    what F12, the viewport and the VR preview export — keeps the old value."""
    settings.id_data.update_tag()


class BTFMaterialSettings(PropertyGroup):
    enabled: BoolProperty(
        update=_tag_material,
        name="Use BTF",
        default=False,
        description="Render this material from a measured or synthetic BTF",
    )
    source: StringProperty(
        update=_tag_material,
        name="BTF Source",
        subtype="FILE_PATH",
        default="",
        # Blender 4.5+ warns about "//" paths unless the property says it supports them.
        options=compat.path_property_options(),
        description="BTFbase material directory (text tables or binary.btf), UBO2014 .btf, "
        "UBO2003/ATRIUM image set (zip or folder) or .btfm file; relative paths (//) are kept "
        "relative to the .blend so render farms find the data",
    )
    uv_map: StringProperty(
        update=_tag_material,
        name="UV Map",
        default="",
        description="UV map for the BTF; empty uses the active render UV map",
    )
    uv_scale: FloatProperty(
        update=_tag_material,
        name="UV Scale",
        default=1.0,
        min=1e-4,
        soft_max=100.0,
        description="Texture repeats per UV unit",
    )
    uv_rotation: FloatProperty(
        update=_tag_material,
        name="UV Rotation",
        default=0.0,
        subtype="ANGLE",
        description="Rotation of the BTF in UV space",
    )
    exposure: FloatProperty(
        update=_tag_material,
        name="Exposure",
        default=0.0,
        soft_min=-10.0,
        soft_max=10.0,
        description="Brightness change in stops (×2 per stop)",
    )

    @classmethod
    def register(cls) -> None:
        bpy.types.Material.btf = PointerProperty(type=cls, name="BTF")

    @classmethod
    def unregister(cls) -> None:
        del bpy.types.Material.btf


classes = (BTFMaterialSettings,)
register, unregister = bpy.utils.register_classes_factory(classes)

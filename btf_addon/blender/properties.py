"""BTF settings stored on each material: ``material.btf``."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, FloatProperty, PointerProperty, StringProperty
from bpy.types import PropertyGroup

from . import compat


class BTFMaterialSettings(PropertyGroup):
    enabled: BoolProperty(
        name="Use BTF",
        default=False,
        description="Render this material from a measured or synthetic BTF",
    )
    source: StringProperty(
        name="BTF Source",
        subtype="FILE_PATH",
        default="",
        # Blender 4.5+ warns about "//" paths unless the property says it supports them.
        options=compat.path_property_options(),
        description="BTFbase material directory or .btfm file; relative paths (//) are kept "
        "relative to the .blend so render farms find the data",
    )
    uv_map: StringProperty(
        name="UV Map",
        default="",
        description="UV map for the BTF; empty uses the active render UV map",
    )
    uv_scale: FloatProperty(
        name="UV Scale",
        default=1.0,
        min=1e-4,
        soft_max=100.0,
        description="Texture repeats per UV unit",
    )
    uv_rotation: FloatProperty(
        name="UV Rotation",
        default=0.0,
        subtype="ANGLE",
        description="Rotation of the BTF in UV space",
    )
    exposure: FloatProperty(
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

"""BTF settings stored on each material: ``material.btf``."""

from __future__ import annotations

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    PointerProperty,
    StringProperty,
)
from bpy.types import PropertyGroup

from . import compat


def _tag_material(settings, _context) -> None:
    """Blender does not tag the material for re-evaluation when an add-on's property changes
    from Python (a script, a driver-less edit): without this, the depsgraph's evaluated copy —
    what F12, the viewport and the VR preview export — keeps the old value."""
    settings.id_data.update_tag()


def _tile_size_changed(settings, context) -> None:
    """An edit of the tile size is the user's own number from now on (Import sets the origin
    back to "assumed" after it writes its guess)."""
    settings.tile_size_origin = "SET"
    _tag_material(settings, context)


def _source_changed(settings, context) -> None:
    """A file picked inside a BTFbase material folder means the folder (the browser of a
    FILE_PATH property picks files): store the folder, then tag as any other change."""
    from .paths import source_for  # paths imports the export chain: only when edited

    normalised = source_for(settings.source)
    if normalised != settings.source:
        settings.source = normalised  # runs this again, with nothing left to change
        return
    _tag_material(settings, context)


class BTFMaterialSettings(PropertyGroup):
    enabled: BoolProperty(
        update=_tag_material,
        name="Use BTF",
        default=False,
        description="Render this material from a measured or synthetic BTF",
    )
    source: StringProperty(
        update=_source_changed,
        name="BTF Source",
        subtype="FILE_PATH",
        default="",
        # Blender 4.5+ warns about "//" paths unless the property says it supports them.
        options=compat.path_property_options(),
        description="BTFbase material folder (or any file in it: text tables or binary.btf), "
        "UBO2014 .btf, UBO2003/ATRIUM image set (zip or folder) or .btfm file; relative paths "
        "(//) are kept relative to the .blend so render farms find the data",
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
    prefer_binary: BoolProperty(
        update=_tag_material,
        name="Use binary.btf",
        default=False,
        description="Read a BTFbase folder from its binary.btf alone instead of table by table "
        "from its text files (which are exact; binary.btf stores some maxima wrapped to 0, "
        "restored where the values allow it)",
    )
    exposure: FloatProperty(
        update=_tag_material,
        name="Exposure",
        default=0.0,
        soft_min=-10.0,
        soft_max=10.0,
        description="Brightness change in stops (×2 per stop)",
    )
    # --- mapping (core/mapping.py documents each; blender/ui/mapping.py draws them) -------
    # Identifiers and defaults are fixed names: settings versioning upgrades files saved
    # before they existed to today's look (NEAREST, UV, no real-world size).
    mapping: EnumProperty(
        update=_tag_material,
        name="Mapping",
        items=(
            ("UV", "UV", "Place the tile by the mesh's UV map", 0),
            (
                "BOX",
                "Box",
                "Project the tile along the object's (or world's) three axes, "
                "blended near edges (triplanar); needs no UV map",
                1,
            ),
        ),
        default="UV",
        description="How the BTF tile is placed on the surface",
    )
    texel_filter: EnumProperty(
        update=_tag_material,
        name="Texel Filter",
        items=(
            (
                "LINEAR",
                "Linear",
                "Blend the 4 nearest texels (as Blender's Image Texture); four decodes per lookup",
                0,
            ),
            ("NEAREST", "Closest", "The nearest texel: blocky in close-ups, 4× cheaper", 1),
        ),
        default="LINEAR",
        description="Spatial filtering of the BTF's texels",
    )
    use_real_world_size: BoolProperty(
        update=_tag_material,
        name="Real-World Size",
        # Off unless chosen: Import BTF turns it on (with the mapping the mesh suits); a
        # material set up by a script keeps one tile per UV unit, as before this existed.
        default=False,
        description="Size the tile from the BTF's physical size and the scene's unit scale "
        "(UV mapping: from the mesh's UV density); UV Scale then multiplies it",
    )
    tile_size_mm: FloatVectorProperty(
        update=_tile_size_changed,
        name="Tile Size (mm)",
        size=2,
        default=(0.0, 0.0),
        min=0.0,
        soft_max=1000.0,
        description="Physical size of one BTF tile (u, v) in millimetres; 0 = the size the "
        "BTF file states (BTFbase states none: Import assumes one from its texel size)",
    )
    #: Where a non-zero tile_size_mm came from, for the Mapping panel: Import's assumption
    #: (BTFbase states no size) or the user's edit. Files from before it: UNKNOWN.
    tile_size_origin: EnumProperty(
        name="Tile Size Origin",
        items=(
            ("UNKNOWN", "Unknown", "Set before the add-on recorded where sizes come from"),
            ("ASSUMED", "Assumed on Import", "Import's texel size times the BTF's texels"),
            ("SET", "Set by You", "Edited on this material"),
        ),
        default="UNKNOWN",
        options={"HIDDEN"},
    )
    assumed_texel_mm: FloatProperty(
        name="Assumed Texel Size (mm)",
        default=0.0,
        min=0.0,
        options={"HIDDEN"},
        description="The texel size Import assumed for this material's tile size",
    )
    uv_offset: FloatVectorProperty(
        update=_tag_material,
        name="Offset",
        size=2,
        default=(0.0, 0.0),
        description="Shift of the tile, in tiles",
    )
    box_space: EnumProperty(
        update=_tag_material,
        name="Box Space",
        items=(
            (
                "OBJECT",
                "Object",
                "The tile moves and turns with the object (keeps its "
                "real-world size when the object is scaled)",
                0,
            ),
            ("WORLD", "World", "The tile stays in the world: objects slide through it", 1),
        ),
        default="OBJECT",
        description="Coordinates the box projection uses",
    )
    box_blend: FloatProperty(
        update=_tag_material,
        name="Blend",
        default=0.2,
        min=0.0,
        max=1.0,
        description="Width of the blend between box projections near edges (0: hard seams)",
    )

    @classmethod
    def register(cls) -> None:
        bpy.types.Material.btf = PointerProperty(type=cls, name="BTF")

    @classmethod
    def unregister(cls) -> None:
        del bpy.types.Material.btf


classes = (BTFMaterialSettings,)
register, unregister = bpy.utils.register_classes_factory(classes)

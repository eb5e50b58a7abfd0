"""The depsgraph's updates → what an ``ExportCache`` must forget."""

from __future__ import annotations

from typing import NamedTuple

import bpy


class ChangedIds(NamedTuple):
    """What changed, by name. A NamedTuple so that callers may unpack it
    (``objects, materials, world = changed_ids(depsgraph)``) or read its fields."""

    objects: set[str]  # objects whose geometry or shading changed
    materials: set[str]
    world: bool  # the World or an image (an environment texture may use it) changed


def changed_ids(depsgraph) -> ChangedIds:
    """What the depsgraph's updates changed. Transform-only changes need no re-export: world
    matrices are applied on every export."""
    objects: set[str] = set()
    materials: set[str] = set()
    world = False
    for update in depsgraph.updates:
        datablock = update.id
        if isinstance(datablock, bpy.types.Object):
            if update.is_updated_geometry or update.is_updated_shading:
                original = datablock.original
                objects.add(original.name if original else datablock.name)
        elif isinstance(datablock, bpy.types.Material):
            materials.add(datablock.name)
        elif isinstance(datablock, bpy.types.World | bpy.types.Image):
            world = True
    return ChangedIds(objects, materials, world)

"""Drag and drop: a ``.btfm`` file, or any file of a BTFbase material folder (its
``all_materialInfo.txt``, ``binary.btf``), dropped on the 3D view imports it as a BTF material
assigned to the selected objects (``btf.import_material``, which loads without a browser when
given a path). Blender's FileHandler matches files by extension; a folder itself cannot be
matched, so a folder is dropped as any file inside it."""

from __future__ import annotations

import bpy

from .import_btf import BTF_OT_import_material

FileHandler = getattr(bpy.types, "FileHandler", None)  # Blender 4.1+; the minimum is 4.2

classes = ()
if FileHandler is not None:

    class BTF_FH_material(FileHandler):
        bl_idname = "BTF_FH_material"
        bl_label = "BTF Material"
        bl_import_operator = BTF_OT_import_material.bl_idname
        bl_file_extensions = ".btfm;.btf;.txt"

        @classmethod
        def poll_drop(cls, context) -> bool:
            area = context.area
            return area is not None and area.type == "VIEW_3D"

    classes = (BTF_FH_material,)

register, unregister = bpy.utils.register_classes_factory(classes)

"""Operators."""

from __future__ import annotations

import json

import bpy
from bpy.types import Operator


class BTF_OT_check_system(Operator):
    """Report what this machine offers the add-on (OpenCL, OpenGL, controllers)"""

    bl_idname = "btf.check_system"
    bl_label = "Check System"
    bl_options = {"INTERNAL"}

    def execute(self, context):
        from ..diagnostics.probes import PROBES

        lines = []
        for name, (probe, hint) in PROBES.items():
            if name == "blender":
                continue  # we are inside Blender
            try:
                result = probe()
                lines.append(f"{name}: ok {json.dumps(result)[:120]}")
            except Exception as exc:  # report, never fail: this operator is the diagnosis
                lines.append(f"{name}: missing ({exc}). {hint}")
        for line in lines:
            self.report({"INFO"} if ": ok" in line else {"WARNING"}, line)
        return {"FINISHED"}


classes = (BTF_OT_check_system,)
register, unregister = bpy.utils.register_classes_factory(classes)

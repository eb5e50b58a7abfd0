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

        for probe in PROBES.values():
            if probe.name == "blender":
                continue  # we are inside Blender
            try:
                facts = probe.check()
            except Exception as exc:  # report, never fail: this operator is the diagnosis
                error = f"{type(exc).__name__}: {exc}"  # as the doctor reports it
                self.report({"WARNING"}, f"{probe.name}: missing ({error}). {probe.hint}")
            else:
                self.report({"INFO"}, f"{probe.name}: ok {json.dumps(facts)[:120]}")
                # The cut above would hide these: each unwritable cache folder on its own line.
                for folder, why in facts.get("unwritable_cache_folders", {}).items():
                    self.report(
                        {"WARNING"},
                        f"{probe.name}: cache folder {folder} cannot be written ({why}); "
                        "a temporary folder is used",
                    )
        return {"FINISHED"}


classes = (BTF_OT_check_system,)
register, unregister = bpy.utils.register_classes_factory(classes)

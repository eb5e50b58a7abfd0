"""Operators."""

from __future__ import annotations

import json

import bpy
from bpy.types import Operator


class BTF_OT_check_system(Operator):
    """Report what this machine offers the add-on: each OpenCL device, whether it builds, which
    one F12 uses; OpenGL, controllers, OpenXR, OpenEXR"""

    bl_idname = "btf.check_system"
    bl_label = "BTF: Check System"
    # Not INTERNAL: found by F3 search and in Render › BTF: Check System, and on the add-on's
    # preferences, where a user looks when F12 falls back to the GLSL path.

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
                self._report_devices(getattr(exc, "facts", {}).get("devices", []))
            else:
                self.report({"INFO"}, f"{probe.name}: ok {json.dumps(facts)[:120]}")
                self._report_devices(facts.get("devices", []))
                # The cut above would hide these: each unwritable cache folder on its own line.
                for folder, why in facts.get("unwritable_cache_folders", {}).items():
                    self.report(
                        {"WARNING"},
                        f"{probe.name}: cache folder {folder} cannot be written ({why}); "
                        "a temporary folder is used",
                    )
        return {"FINISHED"}

    def _report_devices(self, devices: list[dict]) -> None:
        """One line per OpenCL device: the cut facts line above cannot hold them."""
        for d in devices:
            if d["builds"]:
                used = " — F12 renders on this one" if d["used"] else ""
                self.report({"INFO"}, f"opencl device: {d['label']} ({d['type']}): builds{used}")
            else:
                self.report(
                    {"WARNING"},
                    f"opencl device: {d['label']} ({d['type']}): cannot build: {d['reason']}",
                )


def _render_menu(self, _context) -> None:
    self.layout.separator()
    self.layout.operator(BTF_OT_check_system.bl_idname, icon="SYSTEM")


classes = (BTF_OT_check_system,)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register() -> None:
    _register()
    bpy.types.TOPBAR_MT_render.append(_render_menu)


def unregister() -> None:
    bpy.types.TOPBAR_MT_render.remove(_render_menu)
    _unregister()

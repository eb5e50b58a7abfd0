"""Add-on preferences: OpenCL device choice and what the system offers."""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty
from bpy.types import AddonPreferences

from ..cl.devices import best_device_index, list_devices
from .addon import ADDON_PACKAGE

# Dynamic EnumProperty items must stay referenced from Python while Blender shows them, and
# querying OpenCL can take a second: both reasons to compute the list once and keep it here.
_device_items: list[tuple[str, str, str, int]] = []
_device_error: str = ""


def device_items(_self=None, _context=None) -> list[tuple[str, str, str, int]]:
    global _device_error
    if not _device_items:
        _device_items.append(("AUTO", "Automatic", "Best GPU, else the CPU", 0))
        try:
            devices = list_devices()
        except RuntimeError as exc:
            devices = []
            _device_error = str(exc)
        best = best_device_index(devices)
        for i, d in enumerate(devices):
            label = f"{d.name} ({d.type}, {d.platform})" + (" — default" if i == best else "")
            _device_items.append(
                (
                    f"DEV{i}",
                    label,
                    f"{d.compute_units} compute units, {d.global_memory_mb} MB",
                    i + 1,
                )
            )
    return _device_items


class BTF_AddonPreferences(AddonPreferences):
    bl_idname = ADDON_PACKAGE

    opencl_device: EnumProperty(
        name="OpenCL Device",
        description="Device for final renders; Automatic picks the best GPU, else the CPU",
        items=device_items,
    )

    def draw(self, context) -> None:
        layout = self.layout
        layout.prop(self, "opencl_device")
        device_items()
        if _device_error:
            box = layout.box()
            box.label(text=f"OpenCL unavailable: {_device_error}", icon="ERROR")
            box.label(text="Install a GPU driver, or: pip install pocl-binary-distribution")


classes = (BTF_AddonPreferences,)
register, unregister = bpy.utils.register_classes_factory(classes)

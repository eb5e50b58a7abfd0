"""Add-on preferences: OpenCL device choice and what the system offers."""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty, PointerProperty
from bpy.types import AddonPreferences

from ..cl.devices import best_device_index, list_devices
from . import wiimote_preferences
from .addon import ADDON_PACKAGE

#: The ``opencl_device`` identifier of "best GPU, else the CPU".
AUTOMATIC = "AUTO"
#: Device ``i`` of ``list_devices()`` is the identifier ``DEVICE_PREFIX + str(i)``.
DEVICE_PREFIX = "DEV"

# Dynamic EnumProperty items must stay referenced from Python while Blender shows them, and
# querying OpenCL can take a second: both reasons to compute the list once and keep it here.
_device_items: list[tuple[str, str, str, int]] = []
_device_error: str = ""


def device_identifier(index: int | None) -> str:
    """The ``opencl_device`` identifier of device ``index`` of ``list_devices()`` (None:
    automatic)."""
    return AUTOMATIC if index is None else f"{DEVICE_PREFIX}{index}"


def device_index(identifier: str) -> int | None:
    """The inverse of ``device_identifier``: a device index, or None for automatic."""
    if identifier == AUTOMATIC:
        return None
    digits = identifier.removeprefix(DEVICE_PREFIX)
    if digits == identifier or not digits.isdigit():
        raise ValueError(f"not an OpenCL device choice: {identifier!r}")
    return int(digits)


def preferred_device() -> int | None:
    """The device index chosen in this add-on's preferences, or None for automatic (also when
    the add-on runs without a preferences entry, as when a checkout registers itself)."""
    addon = bpy.context.preferences.addons.get(ADDON_PACKAGE)
    preferences = getattr(addon, "preferences", None)
    try:
        return device_index(getattr(preferences, "opencl_device", AUTOMATIC))
    except ValueError:
        # A saved device that is no longer listed (a GPU or driver removed) reads back as "":
        # render on the automatic choice rather than fail.
        return None


def device_items(_self=None, _context=None) -> list[tuple[str, str, str, int]]:
    global _device_error
    if not _device_items:
        _device_items.append((AUTOMATIC, "Automatic", "Best GPU, else the CPU", 0))
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
                    device_identifier(i),
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
    wiimote: PointerProperty(type=wiimote_preferences.BTFWiimotePreferences, name="Wiimote")

    def draw(self, context) -> None:
        layout = self.layout
        layout.prop(self, "opencl_device")
        device_items()
        if _device_error:
            box = layout.box()
            box.label(text=f"OpenCL unavailable: {_device_error}", icon="ERROR")
            box.label(text="Install a GPU driver, or: pip install pocl-binary-distribution")
        wiimote_preferences.draw(layout, self.wiimote)


classes = (BTF_AddonPreferences,)
register, unregister = bpy.utils.register_classes_factory(classes)

"""Add-on preferences: OpenCL device choice and what the system offers."""

from __future__ import annotations

import sys

import bpy
from bpy.props import EnumProperty, PointerProperty
from bpy.types import AddonPreferences

from ..cl.devices import device_report
from .addon import ADDON_PACKAGE
from .wiimote import preferences as wiimote_preferences

#: ``missing_source`` identifiers: what F12 does when a BTF material's source cannot be loaded.
MISSING_FAIL = "FAIL"
MISSING_PINK = "PINK"

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


def _preferences():
    addon = bpy.context.preferences.addons.get(ADDON_PACKAGE)
    return getattr(addon, "preferences", None)


def missing_source_behaviour() -> str:
    """``MISSING_FAIL`` (the default, also without a preferences entry) or ``MISSING_PINK``."""
    return getattr(_preferences(), "missing_source", MISSING_FAIL)


def device_items(_self=None, _context=None) -> list[tuple[str, str, str, int]]:
    global _device_error
    if not _device_items:
        _device_items.append(
            (AUTOMATIC, "Automatic", "The first that builds: GPU, system CPU driver, bundled", 0)
        )
        try:
            rows = device_report()  # probes each device once (cached on disk afterwards)
        except RuntimeError as exc:
            rows = []
            _device_error = str(exc)
        for row in rows:
            status = " — default" if row["used"] else "" if row["builds"] else " — cannot build"
            _device_items.append(
                (
                    device_identifier(row["index"]),
                    row["label"] + status,
                    f"{row['type']}, {row['compute_units']} compute units, "
                    f"{row['global_memory_mb']} MB"
                    + ("" if row["builds"] else f"; cannot build programs: {row['reason']}"),
                    row["index"] + 1,
                )
            )
    return _device_items


def opencl_help() -> str:
    """What to install for OpenCL on this system, in a Blender user's words (no pip)."""
    if sys.platform.startswith("linux"):
        return (
            "The Linux download bundles PoCL, a CPU driver that cannot build on CPUs newer than "
            "its LLVM 14:\ninstall your distribution's PoCL (Debian/Ubuntu: pocl-opencl-icd, "
            "Fedora: pocl) or your GPU's OpenCL driver (NVIDIA, AMD ROCm, Intel compute)."
        )
    if sys.platform == "darwin":
        return "macOS provides OpenCL itself; check that nothing blocks the system framework."
    return "Install your GPU vendor's driver (NVIDIA, AMD or Intel): each includes OpenCL."


class BTF_AddonPreferences(AddonPreferences):
    bl_idname = ADDON_PACKAGE

    opencl_device: EnumProperty(
        name="OpenCL Device",
        description="Device for final renders; Automatic picks the first that builds programs: "
        "a GPU, else a CPU driver of the system, else the bundled PoCL",
        items=device_items,
    )
    missing_source: EnumProperty(
        name="Missing BTF Source",
        description="What a final render does when a BTF material's source cannot be loaded",
        items=[
            (
                MISSING_FAIL,
                "Fail the Render",
                "Stop with an error naming each missing source (render farms see a failed job)",
                0,
            ),
            (
                MISSING_PINK,
                "Render Pink",
                "Render the material in an unmistakable magenta, as Cycles does for a missing "
                "texture, and warn",
                1,
            ),
        ],
        default=MISSING_FAIL,
    )
    wiimote: PointerProperty(type=wiimote_preferences.BTFWiimotePreferences, name="Wiimote")

    def draw(self, context) -> None:
        layout = self.layout
        layout.prop(self, "opencl_device")
        device_items()
        if _device_error:
            box = layout.box()
            box.label(text=f"OpenCL unavailable: {_device_error}", icon="ERROR")
            for line in opencl_help().splitlines():
                box.label(text=line)
        layout.operator("btf.check_system", icon="SYSTEM")
        layout.prop(self, "missing_source")
        wiimote_preferences.draw(layout, self.wiimote)


classes = (BTF_AddonPreferences,)
register, unregister = bpy.utils.register_classes_factory(classes)

"""The Blender layer: the only package that imports bpy.

Submodules register in order and unregister in reverse (hydra_storm's pattern). A failing
registration is never swallowed: Blender shows the exception and the add-on stays disabled.
"""

from __future__ import annotations

import importlib

MODULES = (
    "wiimote_preferences",  # before preferences: BTF_AddonPreferences.wiimote points at it
    "preferences",
    "properties",
    "render_settings",
    "operators",
    "import_btf",
    "engine",
    "ui",
    "film_panel",  # after ui: below the BTF render panel
    "wiimote_overlay",
    "wiimote_operator",
    "stereo_capture",
    "xr",  # after wiimote_overlay: the VR HUD shows the Wiimote's help rows
    "xtal_bridge",  # needs no OpenXR in Blender's build: the loader comes with pyopenxr
)


def _modules():
    return [importlib.import_module(f".{name}", __package__) for name in MODULES]


def register() -> None:
    for module in _modules():
        module.register()


def unregister() -> None:
    for module in reversed(_modules()):
        module.unregister()

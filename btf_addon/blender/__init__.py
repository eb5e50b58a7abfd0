"""The Blender layer: the only package that imports bpy. Rooms by job: ``vr/`` (Blender's VR
session, the XTAL bridge, stereo captures), ``wiimote/``, ``accuracy/`` (Quality vs Time),
``ui/`` (panels), ``tools/`` (import, drag and drop, compress), ``export/`` (depsgraph →
plain scene); the engine, F12, the viewport, sync, preferences and properties stay here.

Submodules register in order and unregister in reverse (hydra_storm's pattern). A failing
registration is never swallowed: Blender shows the exception and the add-on stays disabled.
"""

from __future__ import annotations

import importlib

MODULES = (
    "wiimote.preferences",  # before preferences: BTF_AddonPreferences.wiimote points at it
    "preferences",
    "properties",
    "paths",  # BTF sources as external data: save handlers, File › External Data
    "versioning",  # after the property groups it upgrades
    "render_settings",
    "operators",
    "tools.import_btf",
    "engine",
    "ui.btf_panels",
    "ui.mapping",  # after ui.btf_panels: a child of BTF_PT_material
    "ui.blender_panels",  # Blender's own panels for this engine, by what it honours
    "tools.file_handler",
    "accuracy.operator",  # after ui.btf_panels: its panel is a child of BTF_PT_render_settings
    "bake.operator",  # after ui.btf_panels: its panel is a child of BTF_PT_render_settings
    "ui.film",  # after ui.btf_panels: below the BTF render panel
    "tools.compress",
    "tools.asset_library",  # after ui.btf_panels: a child of BTF_PT_material
    "wiimote.overlay",
    "wiimote.operator",
    "vr.stereo_capture",
    "vr.preview",  # after wiimote.overlay: the VR HUD shows the Wiimote's help rows
    "vr.xtal_bridge",  # needs no OpenXR in Blender's build: the loader comes with pyopenxr
)


def _modules():
    return [importlib.import_module(f".{name}", __package__) for name in MODULES]


def register() -> None:
    _use_extension_kernel_cache()
    for module in _modules():
        module.register()


def _use_extension_kernel_cache() -> None:
    """Compiled OpenCL kernels, BTF importance tables, BVHs and World images in the extension's
    user directory (removed with the extension) instead of ~/.cache. Blender before 4.2, or the
    add-on run from a checkout (not an installed extension), has no such directory: the default
    caches stay."""
    import bpy

    from ..cl import programs
    from ..core.sampling import table_cache
    from ..scene import geometry_cache
    from .addon import ADDON_PACKAGE
    from .export import world_cache

    try:
        folder = bpy.utils.extension_path_user(ADDON_PACKAGE, path="kernel_cache", create=True)
        tables = bpy.utils.extension_path_user(ADDON_PACKAGE, path="importance_cache")
        geometry = bpy.utils.extension_path_user(ADDON_PACKAGE, path="geometry_cache")
        world = bpy.utils.extension_path_user(ADDON_PACKAGE, path="world_cache")
    except (AttributeError, ValueError, KeyError, OSError):
        return
    programs.set_cache_dir(folder)
    table_cache.set_cache_dir(tables)
    geometry_cache.STORE.set_folder(geometry)
    world_cache.STORE.set_folder(world)


def unregister() -> None:
    for module in reversed(_modules()):
        module.unregister()

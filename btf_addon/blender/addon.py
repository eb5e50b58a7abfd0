"""Names shared by the Blender layer."""

from __future__ import annotations

# The extension's own package: "bl_ext.<repo>.btf_materials" when installed as an extension
# (this file is <root>/btf_addon/blender/addon.py), "btf_addon" when imported from a checkout.
ADDON_PACKAGE = (
    __package__.rsplit(".btf_addon.blender", 1)[0]
    if ".btf_addon.blender" in (__package__ or "")
    else "btf_addon"
)

ENGINE_ID = "BTF_RENDER"

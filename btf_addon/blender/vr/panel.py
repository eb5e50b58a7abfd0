"""The "BTF VR" panel (3D view sidebar, VR tab), its settings (``scene.btf_vr``) and the
start/stop operator. Without XR in the Blender build only an explanatory panel registers."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, PointerProperty
from bpy.types import Operator, Panel, PropertyGroup

from .headset_settings import HeadsetProperties, draw_headset_properties

#: What the panel says in a Blender built without OpenXR (bpy.app.build_options.xr_openxr).
NO_XR_LINES = (
    "This Blender was built without OpenXR,",
    "so it cannot start a VR session.",
    "Official Windows and Linux builds have it.",
)


class BTFVRSettings(HeadsetProperties, PropertyGroup):
    """The VR session's settings: the headset's (headset_settings.py, shared with the XTAL
    bridge) and the session's own."""

    controller_actions: EnumProperty(
        name="Controllers",
        items=(
            ("BTF", "BTF Actions", "Controllers change materials, exposure and the environment"),
            (
                "BLENDER",
                "Blender Navigation",
                "Controllers teleport, fly and grab as in "
                "Blender's VR Scene Inspection (its add-on must be enabled)",
            ),
        ),
        default="BTF",
        update=lambda settings, context: _switch_actions(settings, context),
    )
    show_world: BoolProperty(
        name="BTF World",
        default=True,
        description="Draw the World's environment behind the objects; off shows Blender's own "
        "VR background (floor, controllers) around them",
    )

    @classmethod
    def register(cls) -> None:
        bpy.types.Scene.btf_vr = PointerProperty(type=cls, name="BTF VR")

    @classmethod
    def unregister(cls) -> None:
        del bpy.types.Scene.btf_vr


def _switch_actions(settings, context) -> None:
    """Blender syncs one action set at a time: switch it in a running session."""
    if bpy.types.XrSessionState.is_running(context):
        from . import actions as xr_actions

        xr_actions.activate(context, use_btf=settings.controller_actions == "BTF")


class BTF_OT_vr_session_toggle(Operator):
    """Start or stop the VR session with BTF materials drawn in the headset"""

    bl_idname = "btf.vr_session_toggle"
    bl_label = "Toggle BTF VR Session"
    bl_options = {"REGISTER"}

    def execute(self, context):
        # Our draw callback is a custom overlay: it runs only with this switched on.
        context.window_manager.xr_session_settings.show_custom_overlays = True
        try:
            result = bpy.ops.wm.xr_session_toggle()
        except RuntimeError as exc:  # Blender reports a missing runtime/headset this way
            self.report(
                {"ERROR"},
                f"Could not start the VR session ({exc}). Check that an OpenXR runtime is "
                "installed and active (SteamVR, Oculus, WMR, Monado) and the headset is on",
            )
            return {"CANCELLED"}
        return result


class VIEW3D_PT_btf_vr(Panel):
    bl_label = "BTF VR"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "VR"

    def draw(self, context) -> None:
        from . import preview as xr

        layout = self.layout
        settings = context.scene.btf_vr
        running = bpy.types.XrSessionState.is_running(context)
        layout.operator(
            "btf.vr_session_toggle",
            text="Stop VR Session" if running else "Start VR Session",
            icon="PAUSE" if running else "PLAY",
        )
        col = layout.column()
        col.use_property_split = True
        draw_headset_properties(col, settings)
        col.prop(settings, "show_world")
        col.prop(settings, "controller_actions")
        preview = xr.preview()
        if running and preview is not None:
            box = layout.box()
            box.label(text=preview.summary(), icon="ERROR" if preview.error else "INFO")
            for key, eye in sorted(preview.eyes.items()):
                box.label(text=f"{key}: {eye.budget.status()}")
            for message in preview.messages:
                box.label(text=message, icon="ERROR")
        if not context.window_manager.xr_session_settings.show_custom_overlays:
            layout.label(text="Custom overlays are off: BTF is not drawn", icon="ERROR")


class VIEW3D_PT_btf_vr_unavailable(Panel):
    bl_label = "BTF VR"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "VR"

    def draw(self, context) -> None:
        col = self.layout.column()
        col.label(text="VR preview unavailable", icon="ERROR")
        for line in NO_XR_LINES:
            col.label(text=line)


WITH_XR = (BTFVRSettings, BTF_OT_vr_session_toggle, VIEW3D_PT_btf_vr)
WITHOUT_XR = (VIEW3D_PT_btf_vr_unavailable,)
_registered: tuple = ()


def register(xr_available: bool) -> None:
    global _registered
    _registered = WITH_XR if xr_available else WITHOUT_XR
    for cls in _registered:
        bpy.utils.register_class(cls)


def unregister() -> None:
    global _registered
    for cls in reversed(_registered):
        bpy.utils.unregister_class(cls)
    _registered = ()

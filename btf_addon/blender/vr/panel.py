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


#: Why the last start failed, as the panel says it (empty: it did not fail). Blender reports a
#: missing runtime or headset itself: GHOST's XR error goes to ``wm_xr_error_handler``, which
#: puts its message in the window manager's reports and the status bar and frees the XR
#: runtime; ``wm.xr_session_toggle`` then returns CANCELLED without raising. Those messages
#: (GHOST_XrContext.cc, GHOST_XrSession.cc) are what the hints below explain.
START_FAILED_LINES = (
    "The VR session did not start: Blender's message (status bar, Info editor) says why.",
    "'Failed to connect to an OpenXR runtime.': install one and make it active",
    "(SteamVR, Meta/Oculus, Windows Mixed Reality, Monado).",
    "'Failed to get device information. Is a device plugged in?': connect and wake the headset.",
)
NO_WINDOW = "Start the VR session from a window with a 3D viewport (Blender needs a window)"
last_start_failed = False


def _xr_session_toggle(context):
    """Blender's own start/stop (``wm.xr_session_toggle``); a module function for tests."""
    return bpy.ops.wm.xr_session_toggle()


def _is_running(context) -> bool:
    return bool(bpy.types.XrSessionState.is_running(context))


class BTF_OT_vr_session_toggle(Operator):
    """Start or stop the VR session with BTF materials drawn in the headset"""

    bl_idname = "btf.vr_session_toggle"
    bl_label = "Toggle BTF VR Session"
    bl_options = {"REGISTER"}

    def execute(self, context):
        global last_start_failed
        # Our draw callback is a custom overlay: it runs only with this switched on.
        context.window_manager.xr_session_settings.show_custom_overlays = True
        starting = not _is_running(context)
        try:
            result = _xr_session_toggle(context)
        except RuntimeError:  # its poll: no window (background Blender, a script)
            self.report({"ERROR"}, NO_WINDOW)
            return {"CANCELLED"}
        if starting:
            # A missing runtime/headset is reported by Blender itself (its message stays in
            # the status bar: no report of ours on top of it); the panel explains it.
            last_start_failed = "CANCELLED" in result and not _is_running(context)
        return result


class BTF_OT_vr_show_custom_overlays(Operator):
    """Turn on the VR session's Custom Overlays: BTF materials are drawn in the headset as
    one (a session started from the VR Scene Inspection panel leaves them off)"""

    bl_idname = "btf.vr_show_custom_overlays"
    bl_label = "Show BTF in the Headset"
    bl_options = {"REGISTER"}

    def execute(self, context):
        context.window_manager.xr_session_settings.show_custom_overlays = True
        return {"FINISHED"}


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
            box = layout.box()
            box.label(text="Custom overlays are off: BTF is not drawn", icon="ERROR")
            box.operator("btf.vr_show_custom_overlays", icon="OVERLAY")
        if last_start_failed and not running:
            box = layout.box()
            for i, line in enumerate(START_FAILED_LINES):
                box.label(text=line, icon="ERROR" if i == 0 else "NONE")


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


WITH_XR = (
    BTFVRSettings,
    BTF_OT_vr_session_toggle,
    BTF_OT_vr_show_custom_overlays,
    VIEW3D_PT_btf_vr,
)
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

"""The "XTAL Bridge" operator: our renderer straight to an OpenXR headset, Blender staying live.

The bridge (``xr/bridge.py``, bpy-free) owns an EGL OpenGL context, the OpenXR session and its
frame loop; OpenGL and OpenXR calls must stay on the thread that made them, so the bridge runs
in a thread of its own (``BridgeThread``) and Blender's main thread talks to it only through its
thread-safe calls: ``set_scene`` (a re-export after the depsgraph reported changes),
``request_stop``, ``status`` and ``pop_edits`` (controller actions, applied here as undoable
scene edits through the same ``wiimote/edits.py`` ``apply_edit`` as the Wiimote and Blender's VR
session). ``BridgeController`` holds that logic without the modal machinery, so background
Blender (tests, scripts) can drive it; the operator is a timer that calls ``tick`` and shows the
status in the 3D view's header. It needs no OpenXR support in Blender's own build: the loader
comes with the bundled pyopenxr. Esc, or the runtime ending the session, stops it.
"""

from __future__ import annotations

import threading
import traceback
from collections.abc import Callable

import bpy
from bpy.props import EnumProperty, FloatProperty, PointerProperty
from bpy.types import Operator, Panel, PropertyGroup

from ...controllers.actions import ACTION_LABELS
from ...core.errors import BTFError
from ...render.headsets import PROFILES
from ..export import ExportCache, changed_ids, export_scene
from ..sync import bridge_settings, render_settings
from ..wiimote.edits import EditContext, EditSkipped, apply_edit
from .headset_settings import HeadsetProperties, draw_headset_properties

# Export size: the bridge draws at the headset's eye size; the exported camera is unused.
EXPORT_SIZE = (64, 64)


class BTFBridgeSettings(HeadsetProperties, PropertyGroup):
    """The bridge's settings: the headset's (headset_settings.py, shared with Blender's VR
    session) and the bridge's own."""

    profile: EnumProperty(
        name="Headset",
        items=[(key, p.label, p.source) for key, p in PROFILES.items()],
        default="xtal-8k",
        description="Headset profile used where the runtime reports nothing (resolution, FOV, "
        "IPD, refresh); the runtime's own values win",
    )
    resolution_scale: FloatProperty(
        name="Resolution Scale",
        default=1.0,
        min=0.1,
        max=2.0,
        description="Eye images at this fraction of the runtime's recommended size",
    )

    @classmethod
    def register(cls) -> None:
        bpy.types.Scene.btf_bridge = PointerProperty(type=cls, name="BTF XTAL Bridge")

    @classmethod
    def unregister(cls) -> None:
        del bpy.types.Scene.btf_bridge


class BridgeThread(threading.Thread):
    """Runs the bridge's own loop: start, frames until the session ends, close — all on this
    thread, which owns the bridge's OpenGL context. ``error``: what ended it early."""

    def __init__(self, bridge, frames: int | None = None):
        super().__init__(name="btf-xtal-bridge", daemon=True)
        self.bridge, self.frames = bridge, frames
        self.error: BaseException | None = None
        self.started_ok = threading.Event()

    def run(self) -> None:
        from ...xr.bridge import BridgeError

        try:
            self.bridge.start()
            self.started_ok.set()
            while self.bridge.run_frame():
                # Frames submitted, not loop passes (it polls while the session starts).
                if self.frames is not None and self.bridge.frames >= self.frames:
                    self.bridge.request_stop()
                    self.frames = None  # let the runtime take the session down cleanly
        except BridgeError as exc:
            self.error = exc
        except Exception as exc:
            traceback.print_exc()
            self.error = exc
        finally:
            try:
                self.bridge.close()
            except Exception:
                traceback.print_exc()


class BridgeController:
    """One bridge run from Blender: export, thread, re-export on change, controller edits."""

    def __init__(self, scene, view_layer, make_bridge: Callable | None = None):
        self.scene_name, self.view_layer_name = scene.name, view_layer.name
        self.cache = ExportCache()
        self.dirty = False
        self.messages: list[str] = []
        self.ctx = EditContext(scene, view_layer)
        self._make_bridge = make_bridge
        self.thread: BridgeThread | None = None
        self.bridge = None

    @property
    def scene(self):
        return bpy.data.scenes[self.scene_name]

    def _depsgraph(self):
        return self.scene.view_layers[self.view_layer_name].depsgraph

    def start(self, frames: int | None = None) -> None:
        """Export and start the bridge's thread (failures to start surface in ``tick``)."""
        from ...xr.bridge import XRBridge
        from ...xr.controls import vr_controls

        exported = export_scene(self._depsgraph(), *EXPORT_SIZE, cache=self.cache, viewport=True)
        self.messages = list(exported.messages)
        # With the scene's film filter, as F12 and Blender's VR session (blender/sync.py).
        settings = render_settings(self.scene)
        options = bridge_settings(self.scene)
        if self._make_bridge is not None:
            self.bridge = self._make_bridge(exported, settings, options)
        else:
            self.bridge = XRBridge(exported, settings, options, vr_controls())
        self.thread = BridgeThread(self.bridge, frames)
        self.thread.start()
        bpy.app.handlers.depsgraph_update_post.append(self._on_depsgraph_update)

    def _on_depsgraph_update(self, scene, depsgraph) -> None:
        if scene.name == self.scene_name:
            self.cache.invalidate(*changed_ids(depsgraph))
            self.dirty = True

    def tick(self) -> bool:
        """Hand over changes and controller edits; False once the bridge has ended (``error``
        then says why, or None for a clean end)."""
        if self.thread is None:
            return False
        if self.dirty and self.thread.is_alive():
            self.dirty = False
            try:
                exported = export_scene(
                    self._depsgraph(), *EXPORT_SIZE, cache=self.cache, viewport=True
                )
            except BTFError as exc:  # the headset keeps the last good scene meanwhile
                self.messages.append(str(exc))
            else:
                self.messages = list(exported.messages)
                self.bridge.set_scene(exported)
        for edit in self.bridge.pop_edits():
            self._apply(edit)
        if self.thread.is_alive():
            return True
        self._finish()
        return False

    def _apply(self, edit) -> None:
        label = ACTION_LABELS[edit.action][0]
        try:
            self.ctx.target = edit.target
            text = apply_edit(self.ctx, edit)
        except EditSkipped as skipped:
            self.messages.append(f"{label}: {skipped}")
            return
        if text:
            self.messages.append(text)
        if (not edit.continuous or edit.end) and bpy.ops.ed.undo_push.poll():
            bpy.ops.ed.undo_push(message=f"XTAL Bridge: {label}")

    @property
    def error(self) -> BaseException | None:
        return self.thread.error if self.thread is not None else None

    def status_text(self) -> str:
        if self.bridge is None:
            return "XTAL Bridge: not started"
        s = self.bridge.status
        fps = f"{s.fps:.0f} FPS" if s.fps else "– FPS"
        lights = ", ".join(f"{k} {v}" for k, v in sorted(s.lights_per_frame.items())) or "–"
        return (
            f"XTAL Bridge · {s.runtime or 'connecting'} · {s.state} · {fps} · lights/frame "
            f"{lights} · {s.eye_size[0]}×{s.eye_size[1]} per eye ({s.values_from}) · Esc: stop"
        )

    def bake_text(self) -> str:
        """The light bake's status line (what plays back, what is stale); "" without one."""
        return self.bridge.status.bake if self.bridge is not None else ""

    def stop(self, timeout: float = 10.0) -> None:
        """Ask the runtime to end the session and wait for the thread (its context is its own)."""
        if self.bridge is not None and self.thread is not None and self.thread.is_alive():
            self.bridge.request_stop()
            self.thread.join(timeout)
        self._finish()

    def _finish(self) -> None:
        handlers = bpy.app.handlers.depsgraph_update_post
        if self._on_depsgraph_update in handlers:
            handlers.remove(self._on_depsgraph_update)


class BTF_OT_xtal_bridge(Operator):
    """Render the scene's BTF materials straight to an OpenXR headset (XTAL or any other), at
    the headset's resolution, while Blender stays usable. Esc stops"""

    bl_idname = "btf.xtal_bridge"
    bl_label = "XTAL Bridge"
    bl_options = {"REGISTER"}

    _running: BridgeController | None = None

    def invoke(self, context, event):
        if BTF_OT_xtal_bridge._running is not None:
            # Clicking again stops it; the running operator's next tick sees the thread gone.
            BTF_OT_xtal_bridge._running.stop()
            return {"FINISHED"}
        controller = BridgeController(context.scene, context.view_layer)
        try:
            controller.start()
        except Exception as exc:
            self.report({"ERROR"}, f"XTAL Bridge could not start: {exc}")
            return {"CANCELLED"}
        BTF_OT_xtal_bridge._running = controller
        self._timer = context.window_manager.event_timer_add(0.1, window=context.window)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        controller = BTF_OT_xtal_bridge._running
        if controller is None:  # stopped from elsewhere (unregister)
            return self._end(context, {"CANCELLED"}, "")
        if event.type == "ESC" and event.value == "PRESS":
            controller.stop()
            return self._end(context, {"FINISHED"}, "XTAL Bridge stopped")
        if event.type == "TIMER":
            try:
                alive = controller.tick()
            except Exception as exc:
                traceback.print_exc()
                controller.stop()
                self.report({"ERROR"}, f"XTAL Bridge stopped: {exc}")
                return self._end(context, {"CANCELLED"}, "")
            if not alive:
                error = controller.error
                if error is not None:
                    self.report({"ERROR"}, f"XTAL Bridge: {error}")
                    return self._end(context, {"CANCELLED"}, "")
                return self._end(context, {"FINISHED"}, "XTAL Bridge: the session ended")
            if context.area is not None:
                context.area.header_text_set(controller.status_text())
        return {"PASS_THROUGH"}

    def cancel(self, context):
        """Blender ends modal operators itself (a file loaded, Blender quitting)."""
        if BTF_OT_xtal_bridge._running is not None:
            BTF_OT_xtal_bridge._running.stop()
        self._end(context, {"CANCELLED"}, "")

    def _end(self, context, result, message):
        context.window_manager.event_timer_remove(self._timer)
        if context.area is not None:
            context.area.header_text_set(None)
        BTF_OT_xtal_bridge._running = None
        if message:
            self.report({"INFO"}, message)
        return result


class VIEW3D_PT_btf_xtal_bridge(Panel):
    bl_label = "XTAL Bridge"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "VR"

    def draw(self, context) -> None:
        layout = self.layout
        running = BTF_OT_xtal_bridge._running
        layout.operator(
            "btf.xtal_bridge",
            text="Stop XTAL Bridge" if running else "Start XTAL Bridge",
            icon="PAUSE" if running else "PLAY",
        )
        settings = context.scene.btf_bridge
        col = layout.column()
        col.use_property_split = True
        col.enabled = running is None
        # Taken when the bridge starts (stop and start again to change them).
        col.prop(settings, "profile")
        col.prop(settings, "resolution_scale")
        draw_headset_properties(col, settings)
        if running is not None:
            box = layout.box()
            box.label(text=running.status_text().replace(" · Esc: stop", ""))
            bake = running.bake_text()
            if bake:
                box.label(text=bake, icon="LIGHT")
            for message in running.messages[-3:]:
                box.label(text=message)


classes = (BTFBridgeSettings, BTF_OT_xtal_bridge, VIEW3D_PT_btf_xtal_bridge)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register() -> None:
    _register()


def unregister() -> None:
    if BTF_OT_xtal_bridge._running is not None:
        BTF_OT_xtal_bridge._running.stop()
        BTF_OT_xtal_bridge._running = None
    _unregister()

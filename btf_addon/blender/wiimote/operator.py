"""The "Wiimote Control" operator: a thin wrapper around ``WiimoteSession``.

Interactive (``invoke``): connects (or says exactly why not), then polls on a window timer at
100 Hz without ever blocking (every read has timeout 0) and ends on Esc, on a second run of the
operator, or when the controller disappears (a message, the scene as edited so far, and the
panel's button offers to reconnect); Blender ending it without an event (File > Open, New,
Revert) goes through ``cancel``, which ends the session the same way. ``execute`` with a
recording plays it to the end at once: what the tests and a bug-report reproduction run
(timers never fire in background Blender). Every way a session ends closes its device.
"""

from __future__ import annotations

import logging
from pathlib import Path

import bpy
from bpy.props import BoolProperty, StringProperty
from bpy.types import Operator, Panel

from ...controllers.replay import ReplayTransport
from ...controllers.transport import ControllerError
from . import overlay as wiimote_overlay
from .edits import EditContext
from .preferences import current_bindings, wiimote_preferences
from .session import WiimoteSession

log = logging.getLogger(__name__)

POLL_INTERVAL_S = 0.01  # the Wiimote reports at about 100 Hz in continuous mode

#: The one live session (one Wiimote at a time): "session", "timer" (its window timer), "stop"
#: (a second run asked it to end). Empty when none runs.
_running: dict = {}
last_message: list[str] = [""]  # what the panel shows after a session ended


def _view_3d(context, area_pointer: int = 0):
    """(RegionView3D, its WINDOW region, the area's ``as_pointer()``) of a 3D view: the area
    ``area_pointer`` names while it is still on the screen, else the one the operator runs in,
    else the first on the screen; (None, None, 0) headless or when there is none. Looked up
    again on every poll: an area the user closed or joined is freed memory."""
    screen_areas = [
        a for a in (context.screen.areas if context.screen else ()) if a.type == "VIEW_3D"
    ]
    areas = [a for a in screen_areas if area_pointer and a.as_pointer() == area_pointer]
    areas += [context.area] if context.area and context.area.type == "VIEW_3D" else []
    areas += screen_areas
    for area in areas:
        for region in area.regions:
            if region.type == "WINDOW":
                return area.spaces.active.region_3d, region, area.as_pointer()
    return None, None, 0


def make_session(context, replay_path: str = "", realtime: bool = True) -> WiimoteSession:
    """A started session on a recording (``replay_path``) or the first Wiimote. Raises
    ControllerError (no device, permission, kernel driver, bad recording, bad binding) with the
    fix; the device (or recording) is closed again when anything after opening it fails."""
    prefs = wiimote_preferences()
    ir_enabled = prefs.ir_enabled if prefs else True
    sensitivity = prefs.ir_sensitivity if prefs else 3
    bindings = current_bindings()  # before opening: a bad binding must not leave it open
    if replay_path:
        path = bpy.path.abspath(replay_path)
        if not Path(path).is_file():
            raise ControllerError(f"recording not found: {path}")
        transport = ReplayTransport.from_file(path, realtime=realtime)
    else:
        from ...controllers.hid_transport import open_wiimote

        record_to = None
        if prefs is not None and prefs.record_sessions:
            folder = Path(bpy.path.abspath("//")) if bpy.data.filepath else Path(bpy.app.tempdir)
            record_to = folder / "btf_wiimote_session.jsonl"
        transport = open_wiimote(record_to=record_to)
    try:
        r3d, region, _ = _view_3d(context)
        ctx = EditContext(context.scene, context.view_layer, r3d, region)
        session = WiimoteSession(
            transport, ctx, bindings, ir_enabled=ir_enabled, ir_sensitivity=sensitivity
        )
        session.start()
    except BaseException:
        transport.close()
        raise
    return session


def _tag_3d_views(context) -> None:
    for area in context.screen.areas if context.screen else ():
        if area.type == "VIEW_3D":
            area.tag_redraw()


def _shown(session) -> tuple:
    """What a step can change on screen: the edits, the messages and the help overlay."""
    return len(session.applied), len(session.messages), session.ctx.help_visible


class BTF_OT_wiimote_control(Operator):
    """Drive the scene with a Wiimote (and Nunchuk): materials, environment, exposure, view"""

    bl_idname = "btf.wiimote_control"
    bl_label = "Wiimote Control"
    bl_options = {"REGISTER"}  # undo steps are pushed per edit by the session, not per run

    replay_path: StringProperty(
        name="Recording",
        subtype="FILE_PATH",
        default="",
        description="Play a JSONL recording instead of a connected Wiimote",
    )
    realtime: BoolProperty(
        name="Real Time",
        default=True,
        description="Play the recording at its own pace (off: all at once)",
    )

    def execute(self, context):
        if not self.replay_path:
            self.report({"ERROR"}, "a live Wiimote needs the interactive operator (invoke)")
            return {"CANCELLED"}
        try:
            session = make_session(context, self.replay_path, realtime=False)
        except ControllerError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        try:
            why = session.run_to_end()
        finally:
            session.stop()  # releases the recording
        self._report_end(session, why)
        return {"FINISHED"}

    def invoke(self, context, event):
        if "session" in _running:  # a second run stops the live session
            _running["stop"] = True
            return {"FINISHED"}
        try:
            session = make_session(context, self.replay_path, self.realtime)
        except ControllerError as exc:
            self.report({"ERROR"}, str(exc))
            last_message[0] = str(exc).splitlines()[0]
            return {"CANCELLED"}
        self._area = _view_3d(context)[2]
        wiimote_overlay.show(lambda: (session.ctx.help_visible, session.controls.bindings))
        wm = context.window_manager
        self._timer = wm.event_timer_add(POLL_INTERVAL_S, window=context.window)
        _running.clear()
        _running.update(session=session, timer=self._timer)
        wm.modal_handler_add(self)
        last_message[0] = "Wiimote connected"
        self.report({"INFO"}, "Wiimote connected: Home shows the bindings, Esc ends")
        return {"RUNNING_MODAL"}

    def _session(self):
        """This run's live session; None once it ended elsewhere (the add-on was disabled)."""
        timer = getattr(self, "_timer", None)
        return (
            _running.get("session")
            if timer is not None and _running.get("timer") is timer
            else None
        )

    def modal(self, context, event):
        session = self._session()
        if session is None:  # ended elsewhere (the add-on was disabled): clean up, go
            self._cleanup(context)
            return {"CANCELLED"}
        if event.type == "ESC" or _running.get("stop"):
            return self._finish(context, session, "stopped")
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        # The view as it is now: the area may have been closed or joined since the last poll.
        r3d, region, self._area = _view_3d(context, getattr(self, "_area", 0))
        session.ctx.set_view(r3d, region)
        before = _shown(session)
        try:
            alive = session.step()
        except Exception as exc:  # end the session cleanly, then show what went wrong
            log.exception("Wiimote session step failed")
            self._finish(context, session, "stopped")
            last_message[0] = f"Wiimote session failed: {type(exc).__name__}: {exc}"
            self.report({"ERROR"}, last_message[0])
            return {"CANCELLED"}
        if _shown(session) != before:  # an idle session redraws nothing
            _tag_3d_views(context)
        if not alive:
            return self._finish(context, session, session.ended or "")
        return {"PASS_THROUGH"}

    def cancel(self, context):
        """Blender ends the operator without an event (File > Open, New, Revert, quitting):
        end the session as Esc does."""
        session = self._session()
        if session is None:
            self._cleanup(context)
            return
        session.push_undo = False  # the file (and its undo history) is being replaced
        self._finish(context, session, "stopped", redraw=False)

    def _finish(self, context, session, why: str, redraw: bool = True):
        """Stop the session (closes its gestures and the device or recording), remove the
        timer and the overlay, say why it ended."""
        try:
            session.stop()
        finally:
            self._cleanup(context)
        self._report_end(session, why)
        if redraw:  # the panel's button and the overlay change
            _tag_3d_views(context)
        return {"FINISHED"}

    def _cleanup(self, context) -> None:
        timer = getattr(self, "_timer", None)
        if timer is not None:
            context.window_manager.event_timer_remove(timer)
            self._timer = None
        if timer is not None and _running.get("timer") is timer:
            _running.clear()
        if "session" not in _running:  # (a newer session keeps its overlay)
            wiimote_overlay.hide()

    def _report_end(self, session, why: str) -> None:
        if why == "stopped":
            last_message[0] = "Wiimote session ended"
            self.report({"INFO"}, last_message[0])
        elif why == "the recording ended":
            last_message[0] = f"Recording played to the end ({len(session.applied)} edits)"
            self.report({"INFO"}, last_message[0])
        else:
            last_message[0] = f"Wiimote disconnected ({why}); run Wiimote Control to reconnect"
            self.report({"WARNING"}, last_message[0])


class BTF_PT_wiimote(Panel):
    bl_label = "Wiimote"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "BTF"

    def draw(self, context) -> None:
        layout = self.layout
        live = "session" in _running
        layout.operator(
            BTF_OT_wiimote_control.bl_idname,
            text="Stop Wiimote" if live else "Wiimote Control",
            icon="CANCEL" if live else "PLAY",
        )
        if live:
            session = _running["session"]
            battery = session.wiimote.battery
            layout.label(text=f"Battery {battery:.0%}" if battery is not None else "Connected")
            layout.label(text=f"Extension: {session.wiimote.extension or 'none'}")
            if session.messages:
                layout.label(text=session.messages[-1])
        elif last_message[0]:
            layout.label(text=last_message[0], icon="INFO")


classes = (BTF_OT_wiimote_control, BTF_PT_wiimote)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register() -> None:
    _register()


def unregister() -> None:
    """End a live session first: its device closed, its timer and overlay removed. A modal
    handler Blender still holds then finds no session and cancels itself."""
    session, timer = _running.get("session"), _running.get("timer")
    _running.clear()
    if timer is not None:
        bpy.context.window_manager.event_timer_remove(timer)
    wiimote_overlay.hide()
    try:
        if session is not None:
            session.stop()
    finally:
        _unregister()

"""One Wiimote session: driver → step function → scene edits, without any clock of its own.

The modal operator calls ``step()`` on every timer event; tests and the instant replay call
``run_to_end()``. Continuous edits of one step are summed per action and axis before they touch
the scene (one property write per step, not one per report). Undo: one step per discrete edit
and one when a continuous gesture ends, named after the action.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable

import bpy

from ...controllers.actions import ACTION_LABELS, TARGETED, Action, Edit
from ...controllers.bindings import Binding
from ...controllers.controls import Controls
from ...controllers.transport import ControllerDisconnectedError, ControllerError
from ...controllers.wiimote.driver import Wiimote
from .edits import EditContext, EditSkipped, apply_edit
from .pointer import object_under_gaze, object_under_pointer

log = logging.getLogger(__name__)

#: Mode changes the controller acknowledges with a short rumble.
RUMBLE_ON = frozenset({Action.PROGRESSIVE_TOGGLE, Action.HELP_TOGGLE, Action.RESET_VIEW})
PLAYER_LED = 0b0001
HELP_LED = 0b1000


def coalesce(edits: Iterable[Edit]) -> list[Edit]:
    """Sum runs of continuous edits per (action, axis); discrete edits and gesture ends keep
    their place (a run is flushed before them)."""
    out: list[Edit] = []
    pending: dict[tuple[Action, str], Edit] = {}
    for edit in edits:
        if edit.continuous and not edit.end:
            key = (edit.action, edit.axis)
            old = pending.get(key)
            pending[key] = (
                edit
                if old is None
                else Edit(
                    edit.t, edit.action, old.amount + edit.amount, edit.axis, target=edit.target
                )
            )
            continue
        out += pending.values()
        pending.clear()
        out.append(edit)
    out += pending.values()
    return out


class WiimoteSession:
    def __init__(
        self,
        transport,
        ctx: EditContext,
        bindings: Iterable[Binding] | None = None,
        *,
        ir_enabled: bool = True,
        ir_sensitivity: int = 3,
        push_undo: bool = True,
    ) -> None:
        self.wiimote = Wiimote(transport, ir_enabled=ir_enabled, ir_sensitivity=ir_sensitivity)
        self.controls = Controls(bindings)
        self.ctx = ctx
        self.push_undo = push_undo
        self.undo_steps: list[str] = []
        self.messages: list[str] = []
        self.applied: list[tuple[Edit, str]] = []
        self.ended: str | None = None
        self.closed = False  # the transport was released (``stop``)
        self._events_seen = 0

    @property
    def transport(self):
        return self.wiimote.transport

    def start(self) -> None:
        self.ctx.save_view()
        self.wiimote.start()

    def _undo(self, message: str) -> None:
        self.undo_steps.append(message)
        if self.push_undo and bpy.ops.ed.undo_push.poll():
            bpy.ops.ed.undo_push(message=message)

    def _apply(self, edits: Iterable[Edit]) -> None:
        for edit in coalesce(edits):
            label = ACTION_LABELS[edit.action][0]
            if edit.end:
                self._undo(f"Wiimote: {label}")
                continue
            try:
                self.ctx.target = self._target(edit)
                text = apply_edit(self.ctx, edit)
            except EditSkipped as skipped:
                self._say(f"{label}: {skipped}")
                continue
            self.applied.append((edit, text))
            if not edit.continuous:
                self._undo(f"Wiimote: {label}")
                if text:
                    self._say(text)
                if edit.action in RUMBLE_ON and self.ended is None:
                    self._feedback(edit.action)

    def _target(self, edit: Edit) -> str | None:
        """The object a targeted action acts on: the edit's own target, else the object under
        the IR pointer, else, in a running VR session, the object under the headset's gaze
        (None: the active object)."""
        if edit.action not in TARGETED:
            return None
        if edit.target is not None:
            return edit.target
        if edit.pointer:
            return object_under_pointer(self.ctx, edit.pointer)
        xr_state = self.ctx.xr()
        return object_under_gaze(self.ctx.scene, xr_state) if xr_state is not None else None

    def _feedback(self, action: Action) -> None:
        try:
            if action is Action.HELP_TOGGLE:
                self.wiimote.set_leds(PLAYER_LED | (HELP_LED if self.ctx.help_visible else 0))
            self.wiimote.pulse_rumble(0.12)
        except ControllerDisconnectedError:
            pass  # the next poll reports it

    def _say(self, text: str) -> None:
        self.messages.append(text)
        log.info("wiimote: %s", text)

    def _driver_events(self) -> None:
        for event in self.wiimote.events[self._events_seen :]:
            if event.kind in ("extension", "extension-removed", "timeout", "error"):
                self._say(event.text)
        self._events_seen = len(self.wiimote.events)

    def step(self, max_reports: int = 256) -> bool:
        """Poll once (never blocks) and apply the edits; False once the controller is gone
        (``ended`` says why; every gesture is closed and the scene keeps the edits so far)."""
        if self.ended is not None:
            return False
        try:
            samples = self.wiimote.poll(max_reports)
        except ControllerDisconnectedError as exc:
            now = self.transport.now()
            self._apply(self.controls.step(now, self.wiimote.pending))
            self.ended = str(exc)
            self._apply(self.controls.finish(now))
            if self.wiimote.rumble:
                try:
                    self.wiimote.set_rumble(False)  # a recording that ended still listens
                except ControllerError:
                    pass
            self._driver_events()
            return False
        self._apply(self.controls.step(self.transport.now(), samples))
        self._driver_events()
        return True

    def run_to_end(self, max_steps: int = 10_000_000) -> str:
        """Step until the transport ends (a replay), one report per step as the live timer
        sees them at the Wiimote's 100 Hz; returns why it ended."""
        for _ in range(max_steps):
            if not self.step(max_reports=1):
                return self.ended or ""
        raise ControllerError(f"the stream did not end within {max_steps} polls")

    def stop(self) -> None:
        """End the session: on the user's request (still running) close the gestures and turn
        the LEDs off; in any case release the device (or recording file). Idempotent: every
        way a session ends calls it."""
        try:
            if self.ended is None:
                try:
                    self._apply(self.controls.finish(self.transport.now()))
                    try:
                        self.wiimote.set_rumble(False)
                        self.wiimote.set_leds(0)
                    except ControllerError:
                        pass
                finally:
                    self.ended = "stopped"
        finally:
            if not self.closed:
                self.closed = True
                self.transport.close()

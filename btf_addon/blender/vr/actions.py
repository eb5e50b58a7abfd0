"""VR controller actions through Blender's own action maps (issue 11).

When a VR session starts (``bpy.app.handlers.xr_session_start_pre``), ``on_session_start``
turns the data of ``controllers/xr_bindings.py`` into one action map and its OpenXR objects, in
the order of Blender's VR Scene Inspection add-on (``viewport_vr_preview/action_map.py``):
``XrActionMaps.new`` → items (user paths, operator, op mode) → bindings (profile, component
paths, threshold, axis regions) → ``action_set_create`` → ``action_create`` and
``action_binding_create`` per item and binding → ``controller_pose_actions_set`` →
``active_action_set_set``. Blender syncs only the active action set (``wm_xr_session.cc``), so
while ours is active the VR add-on's default navigation actions (teleport, fly, grab) are not.
Ours is built after every other ``xr_session_start_pre`` handler whatever the order they were
added in (``on_session_start`` appends a one-shot ``build_after_other_handlers`` to the end of
the list): the add-on's handler walks every action map of the session and stops at the first
set that cannot be created, so it must never meet ours; built last, ours is the active set.

Every non-pose action calls ``BTF_OT_xr_action`` (``btf.xr_action``) with the action's
identifier. It reads ``event.xr`` (XrEventData: state, aim pose, user path), builds an ``Edit``
of the shared vocabulary and applies it with ``wiimote/edits.py`` ``apply_edit``: targeted actions
(material, exposure) act on the object under the controller's aim ray, else on the active
object; discrete actions push one undo step each; a continuous action (op mode MODAL: an event
every frame while the input is beyond its threshold, one on release) applies
amount = rate · deflection · seconds between events and pushes one undo step when
the gesture ends (the deflection of each event holds until the next, as the Wiimote's
step function integrates). ``register``/``unregister`` add and remove exactly the handler and the
operator; ``blender/vr/preview.py`` calls them only when ``bpy.app.build_options.xr_openxr``.
"""

from __future__ import annotations

import logging
import time

import bpy
from bpy.app.handlers import persistent
from bpy.props import EnumProperty
from bpy.types import Operator

from ...controllers.actions import ACTION_LABELS, TARGETED, Action, Edit
from ...controllers.xr_bindings import (
    ACTION_SET,
    OPERATOR,
    XR_ACTIONS,
    XrAction,
    for_action,
    grip_and_aim,
    is_continuous,
    xr_action,
)
from ..wiimote.edits import EditContext, EditSkipped, apply_edit
from ..wiimote.pointer import object_under_aim

log = logging.getLogger(__name__)


# ------------------------------------------------------------------ the action map
def build_action_map(session_state, context, items: tuple[XrAction, ...] = XR_ACTIONS) -> bool:
    """Create the action map ``ACTION_SET`` from ``items`` on ``session_state`` (an
    XrSessionState) and its OpenXR action set, actions and bindings; make it the active set.
    False (and a log line saying which step) when Blender refuses a step."""
    am = session_state.actionmaps.new(session_state, ACTION_SET, True)
    if am is None:
        log.error("VR: could not create the action map %r", ACTION_SET)
        return False
    for item in items:
        ami = am.actionmap_items.new(item.name, True)
        ami.type = item.type
        for path in item.user_paths:
            ami.user_paths.new(path)
        if item.type == "POSE":
            ami.pose_is_controller_grip = item.pose_is_controller_grip
            ami.pose_is_controller_aim = item.pose_is_controller_aim
        elif item.op:
            ami.op = item.op  # creates op_properties for the registered operator
            ami.op_properties.action = item.action.name
            ami.op_mode = item.op_mode
            ami.bimanual = False
        for binding in item.bindings:
            amb = ami.bindings.new(binding.name, True)
            amb.profile = binding.profile
            for path in binding.component_paths:
                amb.component_paths.new(path)
            if item.type != "POSE":
                amb.threshold = binding.threshold
                amb.axis0_region = binding.axis0_region
                amb.axis1_region = binding.axis1_region
    if not session_state.action_set_create(context, am):
        log.error("VR: action_set_create refused %r", ACTION_SET)
        return False
    for ami in am.actionmap_items:
        if not session_state.action_create(context, am, ami):
            log.error("VR: action_create refused %r", ami.name)
            return False
        for amb in ami.bindings:
            if not session_state.action_binding_create(context, am, ami, amb):
                log.error("VR: action_binding_create refused %r / %r", ami.name, amb.name)
                return False
    grip, aim = grip_and_aim()
    if not session_state.controller_pose_actions_set(context, ACTION_SET, grip, aim):
        log.error("VR: controller_pose_actions_set refused %r, %r", grip, aim)
        return False
    if not session_state.active_action_set_set(context, ACTION_SET):
        log.error("VR: active_action_set_set refused %r", ACTION_SET)
        return False
    return True


def _session_state(context):
    """The session being started (None when none is: e.g. a handler called by hand)."""
    return getattr(context.window_manager, "xr_session_state", None)


@persistent
def on_session_start(*_args) -> None:
    """``xr_session_start_pre`` handler: the session exists (its state is there) and has not
    started yet, the moment Blender expects action sets to be created (it attaches every set
    right after the handlers, ``wm_xr_session_actions_init``, and OpenXR attaches once).

    The action map is NOT built here but by ``build_after_other_handlers``, appended to the end
    of the handler list: Blender's handler loop reads the list's length at every step
    (``bpy_app_generic_callback``), so it runs in this same chain, after every handler that was
    there, the VR Scene Inspection add-on's ``vr_create_actions`` included. That one walks ALL
    action maps of the session and gives up at the first ``action_set_create`` that fails
    (``WM_xr_action_set_create`` fails for a set that exists): had ours been made first, it
    would meet ours, fail, and leave Blender's navigation uncreated."""
    if _session_state(bpy.context) is None:
        return
    handlers = bpy.app.handlers.xr_session_start_pre
    for stale in _deferred_handlers():  # left by a chain that could not remove it: after us
        handlers.remove(stale)
    handlers.append(build_after_other_handlers)


def build_after_other_handlers(*_args) -> None:
    """The deferred half of ``on_session_start``: build the action map, then take itself out of
    the handler list (only when it is the last entry: removing an earlier entry mid-loop would
    make Blender's loop skip the next handler; a leftover is removed at the next start)."""
    handlers = bpy.app.handlers.xr_session_start_pre
    if len(handlers) and handlers[-1] is build_after_other_handlers:
        handlers.pop()
    context = bpy.context
    state = _session_state(context)
    if state is None:
        return
    if build_action_map(state, context):
        settings = getattr(context.scene, "btf_vr", None)
        if settings is not None and settings.controller_actions == "BLENDER":
            activate(context, use_btf=False)


def _deferred_handlers() -> list:
    return [h for h in bpy.app.handlers.xr_session_start_pre if h is build_after_other_handlers]


#: The action set of Blender's VR Scene Inspection add-on (teleport, fly, grab).
BLENDER_ACTION_SET = "blender_default"


def activate(context, use_btf: bool) -> bool:
    """Make our action set or Blender's navigation the active one in the running session
    (Blender syncs only the active set, so the controllers do one or the other). False when no
    session runs or the runtime refuses (the other set was never created)."""
    state = _session_state(context)
    if state is None:
        return False
    return bool(state.active_action_set_set(context, ACTION_SET if use_btf else BLENDER_ACTION_SET))


# ------------------------------------------------------------------ events → edits
def deflection(xr) -> float:
    """The input's value in −1..1: the float state, or the x of a 2D one."""
    return max(-1.0, min(1.0, float(xr.state[0])))


class XrActionRun:
    """One press, or one gesture, of a VR action: XrEventData-like values → Edits → scene.

    ``xr`` needs ``state`` (2 floats), ``controller_location`` (3) and ``controller_rotation``
    (a quaternion, 4): the aim pose Blender puts in every action event. Times are seconds
    (``time.monotonic`` in the operator, any clock in tests)."""

    def __init__(self, ctx: EditContext, item: XrAction, *, push_undo: bool = True) -> None:
        if item.action is None:
            raise ValueError(f"{item.name!r} is a pose action: nothing to apply")
        self.ctx, self.item, self.push_undo = ctx, item, push_undo
        self.action: Action = item.action
        self.last_t: float | None = None
        self.last_deflection = 0.0
        self.gesture_start = 0  # len(applied) when the running gesture began
        self.applied: list[tuple[Edit, str]] = []
        self.undo_steps: list[str] = []
        self.messages: list[str] = []

    @property
    def label(self) -> str:
        return ACTION_LABELS[self.action][0]

    def target(self, xr) -> str | None:
        """The object under the controller's aim ray for targeted actions (None: none hit, or
        not targeted; the edit then acts on the active object)."""
        if self.action not in TARGETED:
            return None
        return object_under_aim(self.ctx.scene, xr.controller_location, xr.controller_rotation)

    def press(self, xr, now: float) -> str:
        """The input went past its threshold: a discrete action is applied now (one undo
        step); a continuous one starts its gesture (nothing moves before time has passed)."""
        if is_continuous(self.item):
            self.last_t, self.last_deflection = now, deflection(xr)
            self.gesture_start = len(self.applied)
            return ""
        return self._apply(Edit(now, self.action, self.item.amount, target=self.target(xr)))

    def update(self, xr, now: float) -> str:
        """A frame of a held continuous input: rate × deflection × seconds since the previous
        event, with the deflection that held over those seconds (the previous event's: left
        Riemann over event times, as the Wiimote's step function, so a full deflection held
        from t0 to the release at t1 gives exactly rate × (t1 − t0))."""
        if self.last_t is None:
            return self.press(xr, now)
        dt, self.last_t = max(0.0, now - self.last_t), now
        amount = self.item.amount * self.last_deflection * dt
        self.last_deflection = deflection(xr)
        if amount == 0.0:
            return ""
        return self._apply(Edit(now, self.action, amount, target=self.target(xr)))

    def release(self, xr, now: float) -> str:
        """The input came back: the last stretch of a gesture, then its end (one undo step)."""
        if not is_continuous(self.item) or self.last_t is None:
            return ""
        text = self.update(xr, now)
        if len(self.applied) > self.gesture_start:  # no empty undo step for a gesture of nothing
            self._apply(Edit(now, self.action, 0.0, end=True))
        self.last_t = None
        return text

    def _apply(self, edit: Edit) -> str:
        if edit.end:
            self._undo()
            return ""
        try:
            self.ctx.target = edit.target
            text = apply_edit(self.ctx, edit)
        except EditSkipped as skipped:
            self.messages.append(f"{self.label}: {skipped}")
            return self.messages[-1]
        self.applied.append((edit, text))
        if not edit.continuous:
            self._undo()
        if text:
            self.messages.append(text)
        return text

    def _undo(self) -> None:
        message = f"VR: {self.label}"
        self.undo_steps.append(message)
        if self.push_undo and bpy.ops.ed.undo_push.poll():
            bpy.ops.ed.undo_push(message=message)


# ------------------------------------------------------------------ the operator
NOT_FROM_VR = "BTF VR actions come from VR controllers (the BTF VR action map), not from here"


def _action_items():
    return [(a.name, ACTION_LABELS[a][0], "") for a in Action]


class BTF_OT_xr_action(Operator):
    """Apply a BTF action from a VR controller (called by the BTF VR action map)"""

    bl_idname = OPERATOR
    bl_label = "BTF VR Action"
    bl_options = {"INTERNAL"}  # undo steps are pushed per edit / gesture, as the Wiimote's

    action: EnumProperty(name="Action", items=_action_items())

    def _item(self, xr) -> XrAction:
        """The action map item that sent the event (its amount and op mode); the first item
        for this action when the event came from another action set."""
        if xr.action_set == ACTION_SET:
            try:
                return xr_action(xr.action)
            except KeyError:
                pass
        return for_action(Action[self.action])

    def execute(self, context):
        """Run without an event (from a script, or 'INVOKE_DEFAULT' without a window)."""
        self.report({"ERROR"}, NOT_FROM_VR)
        return {"CANCELLED"}

    def invoke(self, context, event):
        xr = getattr(event, "xr", None)
        if event.type != "XR_ACTION" or xr is None:
            self.report({"ERROR"}, NOT_FROM_VR)
            return {"CANCELLED"}
        self._run = XrActionRun(EditContext(context.scene, context.view_layer), self._item(xr))
        text = self._run.press(xr, time.monotonic())
        if text:
            self.report({"INFO"}, text)
        if not is_continuous(self._run.item):
            return {"FINISHED"}
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        run = getattr(self, "_run", None)
        xr = getattr(event, "xr", None)
        if run is None:
            return {"CANCELLED"}
        if event.type != "XR_ACTION" or xr is None or xr.action != run.item.name:
            return {"PASS_THROUGH"}  # other input (desktop, other actions) goes on
        now = time.monotonic()
        if event.value == "RELEASE":
            run.release(xr, now)
            return {"FINISHED"}
        run.update(xr, now)
        return {"RUNNING_MODAL"}


classes = (BTF_OT_xr_action,)


def _our_handlers() -> list:
    """This module's session-start handlers (also one left by an earlier load of it)."""
    return [
        h
        for h in bpy.app.handlers.xr_session_start_pre
        if getattr(h, "__name__", "") == on_session_start.__name__
        and getattr(h, "__module__", "") == __name__
    ]


def register() -> None:
    for cls in classes:
        bpy.utils.register_class(cls)
    for handler in _our_handlers():
        bpy.app.handlers.xr_session_start_pre.remove(handler)
    bpy.app.handlers.xr_session_start_pre.append(on_session_start)


def unregister() -> None:
    for handler in _our_handlers() + _deferred_handlers():
        bpy.app.handlers.xr_session_start_pre.remove(handler)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)

"""The VR controllers through the runtime's action system, mapped to the shared vocabulary.

The action set and its bindings are the data of ``controllers/xr_bindings.py`` (the same
actions and interaction profiles as Blender's own VR session) as a ``ControlMap``:
``vr_controls()`` builds it (``controllers/`` is a layer below; tests hand in maps of their
own). One OpenXR action per item
(FLOAT inputs with the item's user paths as subaction paths, POSE inputs for grip and aim),
bindings suggested per profile, the set attached to the session, synced every frame. A float
state beyond the item's threshold is a press: PRESS items give one ``Edit`` per press (rising
edge); MODAL (continuous) items give an edit per frame while held (amount × deflection ×
seconds) and one ``end=True`` edit on release — as ``controllers.actions.Edit`` describes.

Controllers are optional: a runtime that refuses a profile's bindings (it may not know every
profile) is logged and skipped; if the action system fails altogether the bridge runs without
controller input and says so in its status message.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ControlMap:
    """The controller vocabulary as data. ``action_set``: the OpenXR action-set name;
    ``items``: ``controllers.xr_bindings.XrAction``-shaped entries (``name``, ``type``,
    ``user_paths``, ``bindings`` with ``profile``/``component_paths``/``threshold``,
    ``action``, ``amount``); ``make_edit``: ``controllers.actions.Edit`` (called as
    ``make_edit(t, action, amount, end=...)``); ``continuous``: the actions that are
    gestures (``controllers.actions.CONTINUOUS``)."""

    action_set: str
    items: tuple
    make_edit: Callable
    continuous: frozenset


def vr_controls() -> ControlMap:
    """The VR controllers' action set: the same actions and profiles as in Blender's VR session
    (controllers/xr_bindings.py), as the Blender operator and the CLI's bridge use it."""
    from ..controllers import actions, xr_bindings

    return ControlMap(
        xr_bindings.ACTION_SET, xr_bindings.XR_ACTIONS, actions.Edit, actions.CONTINUOUS
    )


@dataclass
class _Input:
    item: object  # an XrAction-shaped entry of ControlMap.items
    handle: object
    subaction_paths: list[tuple[str, int]]  # (user path, XrPath)


class Controls:
    """The action set on one session. ``poll(t, dt)`` syncs and returns the edits."""

    def __init__(self, openxr, instance, session, control_map: ControlMap):
        self.xr, self.instance, self.session = openxr, instance, session
        self.map = control_map
        self.action_set = openxr.create_action_set(
            instance,
            openxr.ActionSetCreateInfo(
                action_set_name=control_map.action_set,
                localized_action_set_name="BTF VR",
                priority=0,
            ),
        )
        self.inputs: list[_Input] = []
        self.pressed: dict[tuple[str, str], bool] = {}
        suggestions: dict[str, list] = {}
        for item in control_map.items:
            paths = [(p, openxr.string_to_path(instance, p)) for p in item.user_paths]
            kind = (
                openxr.ActionType.POSE_INPUT
                if item.type == "POSE"
                else openxr.ActionType.FLOAT_INPUT
            )
            handle = openxr.create_action(
                self.action_set,
                openxr.ActionCreateInfo(
                    action_name=item.name,
                    action_type=kind,
                    subaction_paths=[p for _, p in paths],
                    localized_action_name=item.name.replace("_", " "),
                ),
            )
            if item.type != "POSE":
                self.inputs.append(_Input(item, handle, paths))
            for binding in item.bindings:
                for user, component in zip(item.user_paths, binding.component_paths, strict=True):
                    path = openxr.string_to_path(instance, user + component)
                    suggestions.setdefault(binding.profile, []).append(
                        openxr.ActionSuggestedBinding(handle, path)
                    )
        self.profiles: list[str] = []
        for profile, bindings in suggestions.items():
            try:
                openxr.suggest_interaction_profile_bindings(
                    instance,
                    openxr.InteractionProfileSuggestedBinding(
                        interaction_profile=openxr.string_to_path(instance, profile),
                        suggested_bindings=bindings,
                    ),
                )
                self.profiles.append(profile)
            except openxr.XrException as exc:  # a runtime may not know every profile
                log.info("the runtime refused the bindings for %s: %s", profile, exc)
        openxr.attach_session_action_sets(
            session, openxr.SessionActionSetsAttachInfo(action_sets=[self.action_set])
        )

    def poll(self, t: float, dt: float) -> list:
        """Sync the actions (the session must be FOCUSED for states to be active) and turn
        the float states into edits at time ``t`` (seconds); ``dt``: seconds since the last
        poll (continuous amounts)."""
        openxr = self.xr
        try:
            openxr.sync_actions(
                self.session,
                openxr.ActionsSyncInfo(
                    active_action_sets=[openxr.ActiveActionSet(self.action_set, openxr.NULL_PATH)]
                ),
            )
        except openxr.SessionNotFocused:
            return []
        edits, make_edit = [], self.map.make_edit
        for entry in self.inputs:
            item = entry.item
            threshold = item.bindings[0].threshold if item.bindings else 0.3
            for user, path in entry.subaction_paths:
                state = openxr.get_action_state_float(
                    self.session, openxr.ActionStateGetInfo(entry.handle, path)
                )
                value = float(state.current_state) if state.is_active else 0.0
                key = (item.name, user)
                down = abs(value) > threshold
                was = self.pressed.get(key, False)
                self.pressed[key] = down
                if item.action in self.map.continuous:
                    if down:
                        edits.append(make_edit(t, item.action, item.amount * value * dt))
                    elif was:
                        edits.append(make_edit(t, item.action, 0.0, end=True))
                elif down and not was:
                    edits.append(make_edit(t, item.action, item.amount))
        return edits

    def close(self) -> None:
        try:
            self.xr.destroy_action_set(self.action_set)  # destroys its actions too
        except Exception as exc:
            log.warning("xrDestroyActionSet during shutdown: %s", exc)

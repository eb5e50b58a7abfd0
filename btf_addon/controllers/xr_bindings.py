"""The VR controller actions as data: one OpenXR action set whose actions map to the shared
action vocabulary (``actions.Action``), with bindings for the common interaction profiles.

``blender/vr/actions.py`` turns this into Blender action maps when a VR session starts
(``XrActionMaps.new`` → items → bindings → ``action_set_create``/``action_create``/
``action_binding_create`` → ``controller_pose_actions_set`` → ``active_action_set_set``).
Every string here is a value Blender's RNA accepts (``XrActionMapItem.type``,
``op_mode``, ``XrActionMapBinding.axis0_region``...); the Blender tests check them against the
running Blender's enums.

Component paths come from the OpenXR 1.0 specification's interaction-profile lists (section
6.4, "Interaction Profile Paths"); Blender's own VR Scene Inspection add-on binds the same ones
(``viewport_vr_preview/defaults.py``). A binding lists one component path per user path of its
action, in the same order (Blender refuses a binding whose counts differ).

The mapping (right hand: materials, exposure, environment; left hand: previous material,
reset), per profile:

| action | Oculus Touch | Valve Index | HTC Vive | WMR | Khronos simple |
|---|---|---|---|---|---|
| next material (pointed object) | R trigger | R trigger | R trigger | R trigger | R select |
| previous material | L trigger | L trigger | L trigger | L trigger | L select |
| rotate environment | R stick x | R stick x | R trackpad x | R stick x | — |
| exposure + | R B | R B | R menu | R menu | — |
| exposure − | R A | R A | R squeeze | R squeeze | — |
| reset VR navigation | L stick click | L stick click | L menu | L stick click | R menu |

The Khronos simple controller has only select and menu buttons: it has no axis for the
environment and no spare button for exposure.
"""

from __future__ import annotations

from dataclasses import dataclass

from .actions import CONTINUOUS, Action

#: The one action set (an OpenXR action-set name: lowercase letters, digits, ``-_.``).
ACTION_SET = "btf_vr"
#: The operator every non-pose action calls (``blender/vr/actions.py``).
OPERATOR = "btf.xr_action"
LEFT = "/user/hand/left"
RIGHT = "/user/hand/right"

OCULUS = "/interaction_profiles/oculus/touch_controller"
INDEX = "/interaction_profiles/valve/index_controller"
VIVE = "/interaction_profiles/htc/vive_controller"
WMR = "/interaction_profiles/microsoft/motion_controller"
SIMPLE = "/interaction_profiles/khr/simple_controller"

#: Binding names (unique within an action map item), as Blender's add-on names them.
PROFILE_NAMES: dict[str, str] = {
    OCULUS: "oculus",
    INDEX: "index",
    VIVE: "vive",
    WMR: "wmr",
    SIMPLE: "simple",
}
PROFILES = tuple(PROFILE_NAMES)

#: A trigger (or a button read as 0/1) counts as pressed above this value; a stick axis counts
#: as deflected beyond it (Blender's own bindings use 0.3 for both).
PRESS_THRESHOLD = 0.3
STICK_THRESHOLD = 0.3


@dataclass(frozen=True)
class XrBinding:
    """One interaction profile's inputs for an action: ``component_paths[i]`` is the input on
    the action's ``user_paths[i]``. ``threshold``: the float state beyond which the action is
    active; ``axis0_region``/``axis1_region``: ``ANY``, ``POSITIVE`` or ``NEGATIVE`` (which
    half of an axis counts)."""

    profile: str
    component_paths: tuple[str, ...]
    threshold: float = PRESS_THRESHOLD
    axis0_region: str = "ANY"
    axis1_region: str = "ANY"

    @property
    def name(self) -> str:
        return PROFILE_NAMES[self.profile]


@dataclass(frozen=True)
class XrAction:
    """One action map item.

    ``type``: Blender's ``XrActionMapItem.type`` (``FLOAT``, ``VECTOR2D``, ``POSE``,
    ``VIBRATION``). ``action``: the vocabulary entry the operator applies (None for the pose
    actions, which only give Blender the controllers' poses). ``op_mode``: ``PRESS`` for
    discrete actions (one edit per press), ``MODAL`` for continuous ones (Blender sends an
    event every frame while the input is beyond its threshold, then one on release).
    ``amount``: per press (stops, steps) for discrete actions; per second at full deflection
    for continuous ones (degrees/s), so an edit's amount is amount × deflection × seconds.
    """

    name: str
    type: str
    user_paths: tuple[str, ...]
    bindings: tuple[XrBinding, ...]
    action: Action | None = None
    op_mode: str = "PRESS"
    amount: float = 1.0
    pose_is_controller_grip: bool = False
    pose_is_controller_aim: bool = False

    @property
    def op(self) -> str:
        return OPERATOR if self.action is not None else ""


def _both(profiles: tuple[str, ...], component: str) -> tuple[XrBinding, ...]:
    return tuple(XrBinding(p, (component, component)) for p in profiles)


def _one(
    pairs: tuple[tuple[str, str], ...],
    threshold: float = PRESS_THRESHOLD,
    axis0_region: str = "ANY",
) -> tuple[XrBinding, ...]:
    return tuple(XrBinding(p, (c,), threshold, axis0_region) for p, c in pairs)


_ALL = PROFILES
_TRIGGER = "/input/trigger/value"
_TRIGGERS = (
    (OCULUS, _TRIGGER),
    (INDEX, _TRIGGER),
    (VIVE, _TRIGGER),
    (WMR, _TRIGGER),
    (SIMPLE, "/input/select/click"),  # the simple controller's one "trigger"
)

XR_ACTIONS: tuple[XrAction, ...] = (
    # The poses: Blender needs a grip and an aim pose action for controller drawing and for
    # the aim pose each action event carries (``XrEventData.controller_location/rotation``).
    XrAction(
        "controller_grip",
        "POSE",
        (LEFT, RIGHT),
        _both(_ALL, "/input/grip/pose"),
        pose_is_controller_grip=True,
    ),
    XrAction(
        "controller_aim",
        "POSE",
        (LEFT, RIGHT),
        _both(_ALL, "/input/aim/pose"),
        pose_is_controller_aim=True,
    ),
    XrAction(
        "next_material",
        "FLOAT",
        (RIGHT,),
        _one(_TRIGGERS),
        Action.NEXT_MATERIAL,
    ),
    XrAction(
        "previous_material",
        "FLOAT",
        (LEFT,),
        _one(_TRIGGERS),
        Action.PREVIOUS_MATERIAL,
    ),
    XrAction(
        "rotate_environment",
        "FLOAT",
        (RIGHT,),
        _one(
            (
                (OCULUS, "/input/thumbstick/x"),
                (INDEX, "/input/thumbstick/x"),
                (VIVE, "/input/trackpad/x"),
                (WMR, "/input/thumbstick/x"),
            ),
            STICK_THRESHOLD,
        ),
        Action.ROTATE_ENVIRONMENT,
        op_mode="MODAL",
        amount=45.0,  # °/s at full deflection, the Wiimote's B + D-pad rate
    ),
    XrAction(
        "exposure_up",
        "FLOAT",
        (RIGHT,),
        _one(
            (
                (OCULUS, "/input/b/click"),
                (INDEX, "/input/b/click"),
                (VIVE, "/input/menu/click"),
                (WMR, "/input/menu/click"),
            )
        ),
        Action.EXPOSURE_UP,
        amount=1.0 / 3.0,  # stops per press, as the Wiimote's +
    ),
    XrAction(
        "exposure_down",
        "FLOAT",
        (RIGHT,),
        _one(
            (
                (OCULUS, "/input/a/click"),
                (INDEX, "/input/a/click"),
                (VIVE, "/input/squeeze/click"),
                (WMR, "/input/squeeze/click"),
            )
        ),
        Action.EXPOSURE_DOWN,
        amount=1.0 / 3.0,
    ),
    XrAction(
        "reset_navigation",
        "FLOAT",
        (LEFT,),
        _one(
            (
                (OCULUS, "/input/thumbstick/click"),
                (INDEX, "/input/thumbstick/click"),
                (VIVE, "/input/menu/click"),
                (WMR, "/input/thumbstick/click"),
            )
        ),
        Action.RESET_VIEW,
    ),
    # The simple controller's only other button is on the right hand: its own item, since a
    # binding's component paths follow the item's user paths.
    XrAction(
        "reset_navigation_simple",
        "FLOAT",
        (RIGHT,),
        _one(((SIMPLE, "/input/menu/click"),)),
        Action.RESET_VIEW,
    ),
)

#: What the Khronos simple controller cannot do (no axis, two buttons a hand).
MISSING_ON_SIMPLE = (Action.ROTATE_ENVIRONMENT, Action.EXPOSURE_UP, Action.EXPOSURE_DOWN)


def xr_action(name: str) -> XrAction:
    """The action map item called ``name``; KeyError for an unknown one."""
    for item in XR_ACTIONS:
        if item.name == name:
            return item
    raise KeyError(name)


def for_action(action: Action) -> XrAction:
    """The first item driving ``action`` (its amount and op mode are the same for all)."""
    for item in XR_ACTIONS:
        if item.action is action:
            return item
    raise KeyError(action)


def grip_and_aim() -> tuple[str, str]:
    """The names of the grip and aim pose actions (``controller_pose_actions_set``)."""
    grip = next(i.name for i in XR_ACTIONS if i.pose_is_controller_grip)
    aim = next(i.name for i in XR_ACTIONS if i.pose_is_controller_aim)
    return grip, aim


def is_continuous(item: XrAction) -> bool:
    return item.action in CONTINUOUS

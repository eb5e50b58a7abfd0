"""The action vocabulary every input device maps to (the thesis's "generic controls API", as
data). An action says what changes, never which button asked for it; the Blender layer turns
actions into scene edits (``blender/wiimote/edits.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class Action(Enum):
    """Identifiers are Blender enum identifiers as well; values are their stable numbers."""

    NEXT_MATERIAL = 1
    PREVIOUS_MATERIAL = 2
    NEXT_OBJECT = 3
    ORBIT_CAMERA = 4  # continuous, degrees; axis "YAW" (about world Z) or "PITCH"
    ROTATE_OBJECT = 5  # continuous, degrees; axis "Z" or "X" (world axes)
    ROTATE_ENVIRONMENT = 6  # continuous, degrees about world Z (the World's Mapping node)
    ZOOM_IN = 7  # continuous, stops: 1 = the camera distance halves
    ZOOM_OUT = 8
    LIGHTS_MORE = 9  # lights per redraw + amount
    LIGHTS_FEWER = 10
    EXPOSURE_UP = 11  # stops
    EXPOSURE_DOWN = 12
    PROGRESSIVE_TOGGLE = 13
    HELP_TOGGLE = 14
    SCREENSHOT = 15
    RESET_VIEW = 16


#: Words for the help overlay and the preferences: (label, unit of the amount or rate).
ACTION_LABELS: dict[Action, tuple[str, str]] = {
    Action.NEXT_MATERIAL: ("Next material", ""),
    Action.PREVIOUS_MATERIAL: ("Previous material", ""),
    Action.NEXT_OBJECT: ("Next object", ""),
    Action.ORBIT_CAMERA: ("Orbit camera", "°/s"),
    Action.ROTATE_OBJECT: ("Rotate object", "°/s"),
    Action.ROTATE_ENVIRONMENT: ("Rotate environment", "°/s"),
    Action.ZOOM_IN: ("Zoom in", "stops/s"),
    Action.ZOOM_OUT: ("Zoom out", "stops/s"),
    Action.LIGHTS_MORE: ("Lights per frame +", "lights"),
    Action.LIGHTS_FEWER: ("Lights per frame −", "lights"),
    Action.EXPOSURE_UP: ("Exposure +", "stops"),
    Action.EXPOSURE_DOWN: ("Exposure −", "stops"),
    Action.PROGRESSIVE_TOGGLE: ("Progressive on/off", ""),
    Action.HELP_TOGGLE: ("Help overlay", ""),
    Action.SCREENSHOT: ("Screenshot", ""),
    Action.RESET_VIEW: ("Reset view", ""),
}


@dataclass(frozen=True)
class Edit:
    """One thing to change at time ``t`` (seconds, the report's timestamp).

    Discrete actions: ``amount`` per press (1 for toggles and steps). Continuous actions: the
    amount accumulated since the previous edit (rate × deflection × seconds), several per
    gesture, then one edit with ``end=True`` (amount 0) when the gesture ends: the Blender
    layer pushes one undo step per discrete edit and one per ending gesture. ``target``: what
    the edit acts on when the device names it (an object name, e.g. under the headset's gaze),
    or None; ``pointer``: where the device points ((x, y) in −1..1 of the view, the Wiimote's
    IR camera), for the Blender layer to find the object under it; None when unknown.
    """

    t: float
    action: Action
    amount: float = 1.0
    axis: str = ""
    end: bool = False
    target: str | None = None
    pointer: tuple[float, float] | None = None

    @property
    def continuous(self) -> bool:
        return self.action in CONTINUOUS


#: Actions that act on one object: the pointed-at one when there is a pointer or target.
TARGETED = frozenset(
    {
        Action.NEXT_MATERIAL,
        Action.PREVIOUS_MATERIAL,
        Action.EXPOSURE_UP,
        Action.EXPOSURE_DOWN,
        Action.ROTATE_OBJECT,
    }
)

CONTINUOUS = frozenset(
    {
        Action.ORBIT_CAMERA,
        Action.ROTATE_OBJECT,
        Action.ROTATE_ENVIRONMENT,
        Action.ZOOM_IN,
        Action.ZOOM_OUT,
    }
)

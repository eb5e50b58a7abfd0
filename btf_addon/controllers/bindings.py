"""Bindings from device inputs to actions, as data, and the Wiimote + Nunchuk defaults.

Inputs are names: the Wiimote's buttons (``A``, ``B``, ``ONE``, ``TWO``, ``PLUS``, ``MINUS``,
``HOME``, ``LEFT``, ``RIGHT``, ``UP``, ``DOWN``), the Nunchuk's ``C`` and ``Z``, and axes:
``STICK_X``, ``STICK_Y`` (−1..1), ``ROLL``, ``PITCH`` (degrees of tilt, from the accelerometer).

Kinds:
- ``PRESS``: a discrete action, ``rate`` = amount per press. With ``modifiers`` it is a combo
  (the trigger pressed while every modifier is held).
- ``HOLD``: a continuous action while the trigger (and modifiers) are held, ``rate`` units/s.
- ``AXIS``: continuous, ``rate`` units/s at full deflection (``full_scale``: 1 for a stick, 90°
  for tilt), zero inside ``dead_zone`` (same units as the axis), proportional outside it.
A discrete action (a step, a toggle) takes ``PRESS``; a continuous one (``actions.CONTINUOUS``)
``HOLD`` or ``AXIS``: a binding of another kind is refused when it is made.

A button binding applies only when the modifier buttons held (buttons that are a modifier of
some binding) are exactly its ``modifiers``: with B held, D-pad Left rotates the environment
and does not also step the material. A button that is itself a modifier fires its own PRESS
binding on release, and only when no other binding used it meanwhile (Home alone → help, Home
+ A → reset view, never both).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from enum import Enum

from .actions import CONTINUOUS, Action
from .transport import ControllerError

BUTTONS = ("A", "B", "ONE", "TWO", "PLUS", "MINUS", "HOME", "LEFT", "RIGHT", "UP", "DOWN", "C", "Z")
AXES = ("STICK_X", "STICK_Y", "ROLL", "PITCH")
DPAD = ("LEFT", "RIGHT", "UP", "DOWN")  # tie order when two arrive in one report


class Kind(Enum):
    PRESS = 1
    HOLD = 2
    AXIS = 3


#: The kinds that fit a discrete action (one edit per press) and a continuous one (a gesture
#: of edits, closed when it ends).
DISCRETE_KINDS = frozenset({Kind.PRESS})
CONTINUOUS_KINDS = frozenset({Kind.HOLD, Kind.AXIS})


@dataclass(frozen=True)
class Binding:
    action: Action
    input: str
    kind: Kind = Kind.PRESS
    modifiers: tuple[str, ...] = ()
    rate: float = 1.0
    dead_zone: float = 0.0
    full_scale: float = 1.0
    axis: str = ""

    def __post_init__(self) -> None:
        continuous = self.action in CONTINUOUS
        fitting = CONTINUOUS_KINDS if continuous else DISCRETE_KINDS
        if self.kind not in fitting:
            kinds = " or ".join(sorted(k.name for k in fitting))
            raise ControllerError(
                f"a {self.kind.name} binding cannot drive {self.action.name}, a "
                f"{'continuous' if continuous else 'discrete'} action: use {kinds}"
            )
        valid = AXES if self.kind is Kind.AXIS else BUTTONS
        if self.input not in valid:
            raise ControllerError(f"{self.kind.name} binding input must be one of {valid}")
        for m in self.modifiers:
            if m not in BUTTONS or m == self.input:
                raise ControllerError(f"modifier {m!r} is not a button other than the trigger")
        if self.kind is Kind.AXIS and not 0 <= self.dead_zone < self.full_scale:
            raise ControllerError("dead zone must be in [0, full scale)")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["action"], d["kind"], d["modifiers"] = (
            self.action.name,
            self.kind.name,
            list(self.modifiers),
        )
        return d

    @classmethod
    def from_dict(cls, d: dict) -> Binding:
        try:
            return cls(
                action=Action[d["action"]],
                input=d["input"],
                kind=Kind[d.get("kind", "PRESS")],
                modifiers=tuple(d.get("modifiers", ())),
                rate=float(d.get("rate", 1.0)),
                dead_zone=float(d.get("dead_zone", 0.0)),
                full_scale=float(d.get("full_scale", 1.0)),
                axis=str(d.get("axis", "")),
            )
        except KeyError as exc:
            raise ControllerError(f"binding {d!r}: unknown or missing {exc}") from exc

    def describe(self) -> str:
        """``"B + Left (hold)"`` style text for the help overlay."""
        names = [*self.modifiers, self.input]
        text = " + ".join(n.replace("_", " ").title() for n in names)
        return text + {Kind.PRESS: "", Kind.HOLD: " (hold)", Kind.AXIS: ""}[self.kind]


TILT_DEAD_ZONE_DEG = 10.0  # the accelerometer is imprecise (thesis tester E): ignore small tilt
STICK_DEAD_ZONE = 0.15


def default_bindings() -> tuple[Binding, ...]:
    """The defaults of issue 13 (rates editable in the preferences)."""
    press, hold, axis = Kind.PRESS, Kind.HOLD, Kind.AXIS
    return (
        Binding(Action.PREVIOUS_MATERIAL, "LEFT", press),
        Binding(Action.NEXT_MATERIAL, "RIGHT", press),
        Binding(Action.LIGHTS_MORE, "UP", press, rate=1.0),
        Binding(Action.LIGHTS_FEWER, "DOWN", press, rate=1.0),
        Binding(Action.NEXT_OBJECT, "A", press),
        Binding(Action.ROTATE_OBJECT, "ROLL", axis, ("B",), 90.0, TILT_DEAD_ZONE_DEG, 90.0, "Z"),
        Binding(Action.ROTATE_OBJECT, "PITCH", axis, ("B",), 90.0, TILT_DEAD_ZONE_DEG, 90.0, "X"),
        Binding(Action.ROTATE_ENVIRONMENT, "LEFT", hold, ("B",), -45.0),
        Binding(Action.ROTATE_ENVIRONMENT, "RIGHT", hold, ("B",), 45.0),
        Binding(Action.EXPOSURE_UP, "PLUS", press, rate=1 / 3),
        Binding(Action.EXPOSURE_DOWN, "MINUS", press, rate=1 / 3),
        Binding(Action.HELP_TOGGLE, "HOME", press),
        Binding(Action.PROGRESSIVE_TOGGLE, "ONE", press),
        Binding(Action.SCREENSHOT, "TWO", press),
        Binding(
            Action.ORBIT_CAMERA, "STICK_X", axis, rate=60.0, dead_zone=STICK_DEAD_ZONE, axis="YAW"
        ),
        Binding(
            Action.ORBIT_CAMERA, "STICK_Y", axis, rate=60.0, dead_zone=STICK_DEAD_ZONE, axis="PITCH"
        ),
        Binding(Action.ZOOM_IN, "C", hold, rate=1.0),
        Binding(Action.ZOOM_OUT, "Z", hold, rate=1.0),
        Binding(Action.RESET_VIEW, "A", press, ("HOME",)),
    )


def help_lines(bindings: tuple[Binding, ...]) -> list[tuple[str, str]]:
    """(inputs, what they do) per binding, for the help overlay and the user guide:
    ``("B + Left (hold)", "Rotate environment −45 °/s")``."""
    from .actions import ACTION_LABELS, CONTINUOUS

    lines = []
    for b in bindings:
        label, unit = ACTION_LABELS[b.action]
        axis = f" {b.axis.lower()}" if b.axis else ""
        if b.action in CONTINUOUS:
            rate = f"{b.rate:g}".replace("-", "−")
            text = f"{label}{axis} {rate} {unit}"
        elif unit and b.rate != 1.0:
            text = f"{label} {b.rate:.3g} {unit}"
        else:
            text = label
        lines.append((b.describe(), text))
    return lines

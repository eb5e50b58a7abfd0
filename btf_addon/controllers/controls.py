"""The step function: controller samples (time-stamped) → edits, synchronously.

``Controls.step(now, samples)`` is all the Blender operator calls: it needs no clock of its own
(times come from the reports), so tests feed it recorded or hand-made samples and get the same
edits the live operator would make.

Continuous actions integrate left-Riemann over the report times: between two samples at t0 and
t1 the state seen at t0 acts for t1 − t0 seconds. A button pressed at t0 and released at t1 thus
contributes rate × (t1 − t0) exactly.

D-pad dominance (a thesis tester's complaint): of the directions held, only the first pressed
counts; a direction pressed while another is held, or pressed in the same report as an earlier
one in ``bindings.DPAD`` order, is ignored until it is released, so a thumb rolling across the
pad never leaks into the perpendicular direction.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from .actions import Action, Edit
from .bindings import DPAD, Binding, Kind, default_bindings
from .wiimote.buttons import button_names
from .wiimote.driver import Sample
from .wiimote.ir import pointer as ir_pointer


@dataclass(frozen=True)
class InputState:
    """What the bindings read: buttons held (after D-pad dominance) and axis values."""

    t: float
    held: frozenset[str]
    axes: dict[str, float]
    pointer: tuple[float, float] | None = None


def input_state(sample: Sample) -> tuple[frozenset[str], dict[str, float]]:
    """A driver Sample → (buttons held, axes), Nunchuk buttons and stick included."""
    held = set(button_names(sample.buttons))
    axes: dict[str, float] = {}
    if sample.tilt_deg is not None:
        axes["ROLL"], axes["PITCH"] = sample.tilt_deg
    if sample.nunchuk is not None:
        axes["STICK_X"], axes["STICK_Y"] = sample.nunchuk.stick
        held |= {name for name, on in (("C", sample.nunchuk.c), ("Z", sample.nunchuk.z)) if on}
    return frozenset(held), axes


class Controls:
    def __init__(self, bindings: Iterable[Binding] | None = None) -> None:
        self.bindings = tuple(default_bindings() if bindings is None else bindings)
        self.modifier_buttons = frozenset(m for b in self.bindings for m in b.modifiers)
        self._state: InputState | None = None
        self._t_integrated: float | None = None
        self._dpad_order: list[str] = []  # dominant first
        self._dpad_blocked: set[str] = set()
        self._used_modifiers: set[str] = set()
        self._gestures: set[Action] = set()

    # --------------------------------------------------------------- helpers
    def _dominance(self, held: frozenset[str]) -> frozenset[str]:
        previous = set(self._dpad_order) | self._dpad_blocked
        self._dpad_order = [d for d in self._dpad_order if d in held]
        self._dpad_blocked &= held
        for direction in DPAD:
            if direction in held and direction not in previous:
                if self._dpad_order:
                    self._dpad_blocked.add(direction)
                else:
                    self._dpad_order.append(direction)
        return held - self._dpad_blocked

    def _applies(self, binding: Binding, held: frozenset[str]) -> bool:
        if not all(m in held for m in binding.modifiers):
            return False
        if binding.kind is Kind.AXIS:
            return True
        others = (held & self.modifier_buttons) - {binding.input}
        return others == set(binding.modifiers)

    def _value(self, binding: Binding, state: InputState) -> float:
        """The binding's deflection in −1..1 in ``state`` (0 when inactive)."""
        if not self._applies(binding, state.held):
            return 0.0
        if binding.kind is Kind.HOLD:
            return 1.0 if binding.input in state.held else 0.0
        if binding.kind is Kind.AXIS:
            v = state.axes.get(binding.input, 0.0)
            if abs(v) <= binding.dead_zone:
                return 0.0
            return max(-1.0, min(1.0, v / binding.full_scale))
        return 0.0

    def _integrate(self, t: float, edits: list[Edit]) -> None:
        state, t0 = self._state, self._t_integrated
        if state is None or t0 is None or t <= t0:
            return
        for binding in self.bindings:
            if binding.kind is Kind.PRESS:
                continue
            value = self._value(binding, state)
            if value:
                amount = binding.rate * value * (t - t0)
                edits.append(Edit(t, binding.action, amount, binding.axis, pointer=state.pointer))
        self._t_integrated = t

    def _gesture_edges(self, t: float, edits: list[Edit]) -> None:
        active = set()
        if self._state is not None:
            for binding in self.bindings:
                if binding.kind is not Kind.PRESS and self._value(binding, self._state):
                    active.add(binding.action)
                    self._used_modifiers |= set(binding.modifiers)
        for action in sorted(self._gestures - active, key=lambda a: a.value):
            edits.append(Edit(t, action, 0.0, end=True))
        self._gestures = active

    def _presses(self, t: float, before: frozenset[str], held: frozenset[str], edits) -> None:
        pressed, released = held - before, before - held
        for binding in self.bindings:
            if binding.kind is not Kind.PRESS:
                continue
            if binding.input in self.modifier_buttons:
                # A modifier's own action fires on release, if nothing used it meanwhile.
                if binding.input not in released:
                    continue
                if binding.input in self._used_modifiers:
                    continue
                if not self._applies(binding, held | {binding.input}):
                    continue
            elif binding.input not in pressed or not self._applies(binding, held):
                continue
            pointer = self._state.pointer if self._state else None
            edits.append(Edit(t, binding.action, binding.rate, binding.axis, pointer=pointer))
            self._used_modifiers |= set(binding.modifiers)
        self._used_modifiers -= released
        self._used_modifiers &= held

    # ------------------------------------------------------------------- API
    def step(self, now: float, samples: Iterable[Sample]) -> list[Edit]:
        """Edits for ``samples`` (in time order) and the time up to ``now``."""
        edits: list[Edit] = []
        for sample in samples:
            held, axes = input_state(sample)
            pointer = ir_pointer(sample.ir_dots) if sample.ir_dots else None
            self.feed(sample.t, held, axes, edits, pointer)
        if self._t_integrated is not None and now > self._t_integrated:
            self._integrate(now, edits)
        return edits

    def feed(
        self,
        t: float,
        held: frozenset[str],
        axes: dict[str, float],
        edits: list[Edit],
        pointer: tuple[float, float] | None = None,
    ) -> None:
        """One input state at time ``t`` (any device: the VR controllers feed these too);
        ``pointer``: where the device points now ((x, y) in −1..1), copied onto the edits."""
        if self._t_integrated is None:
            self._t_integrated = t
        self._integrate(t, edits)
        before = self._state.held if self._state else frozenset()
        held = self._dominance(held)
        self._state = InputState(t, held, dict(axes), pointer)
        self._presses(t, before, held, edits)
        self._gesture_edges(t, edits)

    def finish(self, t: float) -> list[Edit]:
        """End every gesture (the stream ended or the controller went away) without
        integrating further: nothing moves after the last report."""
        edits = [Edit(t, a, 0.0, end=True) for a in sorted(self._gestures, key=lambda a: a.value)]
        self._gestures.clear()
        self._state = None
        self._t_integrated = None
        return edits

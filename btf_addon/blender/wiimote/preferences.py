"""Wiimote bindings in the add-on preferences: editable, saved with Blender's preferences and
reset to the defaults of ``controllers/bindings.py``.

``BTF_AddonPreferences.wiimote`` points at ``BTFWiimotePreferences`` (the hook in
``preferences.py``); an empty binding list means "the defaults", so a fresh install needs no
set-up step and a reset is "clear and fill with the defaults".
"""

from __future__ import annotations

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    StringProperty,
)
from bpy.types import Operator, PropertyGroup

from ...controllers.actions import ACTION_LABELS, Action
from ...controllers.bindings import AXES, BUTTONS, Binding, Kind, default_bindings
from ...controllers.transport import ControllerError
from ..addon import ADDON_PACKAGE

NONE = "NONE"
ACTION_ITEMS = [(a.name, ACTION_LABELS[a][0], "", a.value) for a in Action]
KIND_ITEMS = [
    (Kind.PRESS.name, "Press", "A discrete action per press (a combo with a modifier)", 1),
    (Kind.HOLD.name, "Hold", "Continuous while held; rate in units per second", 2),
    (Kind.AXIS.name, "Axis", "Continuous, proportional to a stick or tilt axis", 3),
]
INPUT_ITEMS = [
    (name, name.replace("_", " ").title(), "", i) for i, name in enumerate(BUTTONS + AXES)
]
MODIFIER_ITEMS = [(NONE, "None", "", 0)] + [
    (name, name.title(), "", i + 1) for i, name in enumerate(BUTTONS)
]


class BTFWiimoteBinding(PropertyGroup):
    action: EnumProperty(name="Action", items=ACTION_ITEMS)
    input: EnumProperty(name="Input", items=INPUT_ITEMS)
    kind: EnumProperty(name="Kind", items=KIND_ITEMS)
    modifier: EnumProperty(name="Modifier", items=MODIFIER_ITEMS, default=NONE)
    rate: FloatProperty(name="Rate", default=1.0, description="Amount per press, or per second")
    dead_zone: FloatProperty(name="Dead Zone", default=0.0, min=0.0)
    full_scale: FloatProperty(name="Full Scale", default=1.0, min=1e-3)
    axis: StringProperty(
        name="Axis", default="", description="YAW/PITCH for orbit, Z/X for rotation"
    )

    def to_binding(self) -> Binding:
        return Binding(
            Action[self.action],
            self.input,
            Kind[self.kind],
            () if self.modifier == NONE else (self.modifier,),
            self.rate,
            self.dead_zone,
            self.full_scale,
            self.axis,
        )

    def set_from(self, binding: Binding) -> None:
        self.action, self.input, self.kind = binding.action.name, binding.input, binding.kind.name
        self.modifier = binding.modifiers[0] if binding.modifiers else NONE
        self.rate, self.dead_zone = binding.rate, binding.dead_zone
        self.full_scale, self.axis = binding.full_scale, binding.axis


class BTFWiimotePreferences(PropertyGroup):
    bindings: CollectionProperty(type=BTFWiimoteBinding)
    ir_enabled: BoolProperty(name="IR Camera", default=True)
    ir_sensitivity: IntProperty(name="IR Sensitivity", default=3, min=1, max=5)
    record_sessions: BoolProperty(
        name="Record Sessions",
        default=False,
        description="Write every session to a JSONL recording beside the .blend (bug reports)",
    )

    def fill_defaults(self) -> None:
        self.bindings.clear()
        for binding in default_bindings():
            self.bindings.add().set_from(binding)


def wiimote_preferences():
    """This add-on's Wiimote preferences, or None (a checkout registered without an add-on
    entry has no preferences)."""
    addon = bpy.context.preferences.addons.get(ADDON_PACKAGE)
    return getattr(getattr(addon, "preferences", None), "wiimote", None)


def current_bindings() -> tuple[Binding, ...]:
    """The bindings from the preferences; the defaults when none are stored. A binding that no
    longer validates raises ControllerError naming it."""
    prefs = wiimote_preferences()
    if prefs is None or not prefs.bindings:
        return default_bindings()
    out = []
    for i, item in enumerate(prefs.bindings):
        try:
            out.append(item.to_binding())
        except ControllerError as exc:
            raise ControllerError(f"Wiimote binding {i + 1}: {exc}") from exc
    return tuple(out)


class BTF_OT_wiimote_reset_bindings(Operator):
    """Replace the Wiimote bindings with the defaults"""

    bl_idname = "btf.wiimote_reset_bindings"
    bl_label = "Reset Wiimote Bindings"
    bl_options = {"INTERNAL"}

    def execute(self, context):
        prefs = wiimote_preferences()
        if prefs is None:
            self.report({"ERROR"}, "the add-on has no preferences entry")
            return {"CANCELLED"}
        prefs.fill_defaults()
        return {"FINISHED"}


def draw(layout, prefs) -> None:
    """The Wiimote box of the add-on preferences."""
    box = layout.box()
    box.label(text="Wiimote", icon="EVENT_W")
    row = box.row()
    row.prop(prefs, "ir_enabled")
    row.prop(prefs, "ir_sensitivity")
    box.prop(prefs, "record_sessions")
    if not prefs.bindings:
        box.label(text="Default bindings (reset to edit them)")
    for item in prefs.bindings:
        row = box.row(align=True)
        row.prop(item, "modifier", text="")
        row.prop(item, "input", text="")
        row.prop(item, "kind", text="")
        row.prop(item, "action", text="")
        row.prop(item, "rate")
        if item.kind == Kind.AXIS.name:
            row.prop(item, "dead_zone", text="Dead")
            row.prop(item, "full_scale", text="Full")
        if item.action in (Action.ORBIT_CAMERA.name, Action.ROTATE_OBJECT.name):
            row.prop(item, "axis", text="")
    box.operator(BTF_OT_wiimote_reset_bindings.bl_idname, icon="LOOP_BACK")


classes = (BTFWiimoteBinding, BTFWiimotePreferences, BTF_OT_wiimote_reset_bindings)
register, unregister = bpy.utils.register_classes_factory(classes)

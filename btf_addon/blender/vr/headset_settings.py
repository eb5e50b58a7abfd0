"""The headset settings Blender's VR session (``scene.btf_vr``, panel.py) and the XTAL bridge
(``scene.btf_bridge``, xtal_bridge.py) share: declared once here, so each idea has one meaning,
one default and one range in both groups (tests/blender/test_headset_settings.py). Their plain
values are ``gl/eye.HeadsetSettings`` (read in blender/sync.py), and both paths draw each eye
with ``gl/eye.HeadsetEye``.

The property names are those the VR group always had, so files keep loading; the bridge's
group gained ``lights_mode`` and ``lights_per_frame`` (defaults: what it did before). The one
default that moved is ``frame_budget_ms`` of the VR group, 11 → 0 ("the headset's display
period"), which the VR session, never told that period, holds as the same 11 ms
(render/frame_budget.py ``DEFAULT_BUDGET_S``); blender/versioning.py writes 11 into older files
anyway, so they show what they were saved with.
"""

from __future__ import annotations

from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty


class HeadsetProperties:
    """A base of both PropertyGroups: Blender registers the annotations of a group's bases too."""

    lights_mode: EnumProperty(
        name="Lights per Frame",
        items=(
            ("BUDGET", "Frame Budget", "As many lights per frame as fit the frame-time budget"),
            ("FIXED", "Fixed", "The same number of lights every frame"),
        ),
        default="BUDGET",
        description="How many virtual lights each frame adds: as many as fit the frame budget, "
        "or a fixed number",
    )
    frame_budget_ms: FloatProperty(
        name="Frame Budget",
        default=0.0,
        min=0.0,
        max=100.0,
        description="Milliseconds per frame that lights per frame adapt to (11 ms holds 90 Hz); "
        "0 takes the headset's display period (the runtime's for the XTAL Bridge; Blender's "
        "VR session is not told it and holds 11 ms)",
    )
    lights_per_frame: IntProperty(
        name="Lights per Frame",
        default=5,
        min=1,
        soft_max=64,
        description="Virtual lights added per frame while the head moves",
    )
    lights_total: IntProperty(
        name="Total Lights",
        default=200,
        min=1,
        soft_max=4096,
        max=65536,
        description="Virtual lights accumulated while the head is still",
    )
    exposure: FloatProperty(
        name="Exposure",
        default=0.0,
        soft_min=-10.0,
        soft_max=10.0,
        description="Brightness in the headset, in stops",
    )
    show_hud: BoolProperty(
        name="HUD",
        default=True,
        description="Material, lights and frame time on a panel floating below the view",
    )


def headset_values(props) -> dict:
    """``HeadsetSettings``'s fields from either group (blender/sync.py builds both paths'
    settings with it)."""
    fixed = props.lights_mode == "FIXED"
    return {
        "lights_total": props.lights_total,
        "lights_per_frame": props.lights_per_frame if fixed else None,
        "budget_s": props.frame_budget_ms / 1e3 if props.frame_budget_ms > 0 else None,
        "exposure": props.exposure,
        "show_hud": props.show_hud,
    }


def draw_headset_properties(layout, settings) -> None:
    """The shared settings as both panels show them (the budget or the fixed K, by mode)."""
    layout.prop(settings, "lights_mode")
    if settings.lights_mode == "BUDGET":
        layout.prop(settings, "frame_budget_ms", text="Budget (ms)")
    else:
        layout.prop(settings, "lights_per_frame")
    for name in ("lights_total", "exposure", "show_hud"):
        layout.prop(settings, name)

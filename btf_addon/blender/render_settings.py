"""Render settings of the BTF engine, stored on the scene: ``scene.btf_render``."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty, PointerProperty
from bpy.types import PropertyGroup


class BTFRenderSettings(PropertyGroup):
    lights_total: IntProperty(
        name="Virtual Lights",
        default=256,
        min=1,
        max=4096,
        description="N: importance-sampled directional lights that stand in for the World",
    )
    lights_per_redraw: IntProperty(
        name="Lights per Redraw",
        default=5,
        min=1,
        max=512,
        description="K: lights added to the viewport image per redraw until all N are in",
    )
    progressive: BoolProperty(
        name="Progressive",
        default=True,
        description="Refine the viewport K lights at a time; off draws all N every redraw",
    )
    lighting: EnumProperty(
        name="Lighting",
        items=[
            ("ENVIRONMENT", "Environment", "Virtual lights from the World's environment", 0),
            ("HEADLIGHT", "Headlight", "One light from the viewer (fast material checks)", 1),
        ],
        default="ENVIRONMENT",
    )
    final_mode: EnumProperty(
        name="Final Render",
        items=[
            (
                "VIRTUAL",
                "Virtual Lights",
                "Deterministic: exactly the N virtual lights, as the "
                "viewport (no noise, an approximation of the World)",
                0,
            ),
            (
                "SAMPLED",
                "Sampled",
                "Monte Carlo: the World sampled continuously with MIS "
                "(noise that falls with the samples, no approximation)",
                1,
            ),
        ],
        default="VIRTUAL",
    )
    max_bounces: IntProperty(
        name="Max Bounces",
        default=4,
        min=0,
        max=64,
        description="Indirect reflections in the Sampled final render",
    )
    samples: IntProperty(
        name="Samples",
        default=64,
        min=1,
        max=65536,
        description="Samples per pixel of the Sampled final render",
    )
    seed: IntProperty(
        name="Seed",
        default=0,
        min=0,
        description="Randomisation of the virtual lights' low-discrepancy points",
    )

    @classmethod
    def register(cls) -> None:
        bpy.types.Scene.btf_render = PointerProperty(type=cls, name="BTF Render")

    @classmethod
    def unregister(cls) -> None:
        del bpy.types.Scene.btf_render


classes = (BTFRenderSettings,)
register, unregister = bpy.utils.register_classes_factory(classes)

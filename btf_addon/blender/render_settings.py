"""Render settings of the BTF engine, stored on the scene: ``scene.btf_render``."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty
from bpy.types import PropertyGroup

from ..render.settings import FinalMode, Lighting

# The enums' identifiers and numbers are the Python enums' names and values (one vocabulary:
# RenderSettings.from_properties reads them back by name); only the words shown live here.
LIGHTING_LABELS = {
    Lighting.ENVIRONMENT: ("Environment", "Virtual lights from the World's environment"),
    Lighting.HEADLIGHT: ("Headlight", "One light from the viewer (fast material checks)"),
}
FINAL_MODE_LABELS = {
    FinalMode.VIRTUAL: (
        "Virtual Lights",
        "Deterministic: exactly the N virtual lights, as the viewport (no noise, an "
        "approximation of the World)",
    ),
    FinalMode.SAMPLED: (
        "Sampled",
        "Monte Carlo: the World sampled continuously with MIS (noise that falls with the "
        "samples, no approximation)",
    ),
}


def enum_items(labels: dict) -> list[tuple[str, str, str, int]]:
    """EnumProperty items (identifier, name, description, number) from {member: (name,
    description)}, with the member's name and value as identifier and number."""
    return [(member.name, name, text, member.value) for member, (name, text) in labels.items()]


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
        items=enum_items(LIGHTING_LABELS),
        default=Lighting.ENVIRONMENT.name,
    )
    final_mode: EnumProperty(
        name="Final Render",
        items=enum_items(FINAL_MODE_LABELS),
        # Sampled converges to the true image; Virtual Lights stays for previews that match
        # the viewport. Files saved before this default keep 'VIRTUAL' (settings versioning).
        default=FinalMode.SAMPLED.name,
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
    use_antialiasing: BoolProperty(
        name="Anti-Aliasing",
        default=True,
        description="Spread each pixel's samples over the film's pixel filter (Film panel); "
        "off traces every ray through the pixel centre, as files made before it",
    )
    aa_samples: IntProperty(
        name="Anti-Aliasing Samples",
        default=16,
        min=1,
        max=1024,
        description="Virtual Lights final render: rays per pixel spread over the pixel filter, "
        "the N lights split between them (about the cost of one ray per pixel)",
    )
    btf_importance_sampling: BoolProperty(
        name="BTF Importance Sampling",
        default=True,
        description="Sampled final render: continue paths from measured BTFs by a table of "
        "their own values (built once per material, about a second) instead of cosine "
        "sampling alone; less noise on glossy materials, about 10 % more time per sample",
    )
    clamp_indirect: FloatProperty(
        name="Clamp Indirect",
        default=10.0,
        min=0.0,
        soft_max=100.0,
        description="Sampled final render: scale a sample's indirect light down so that no "
        "channel exceeds this value, which removes fireflies at the cost of a little energy "
        "(as Cycles' Clamp Indirect); 0 turns it off",
    )
    samples_per_camera_ray: IntProperty(
        name="Samples per Camera Ray",
        default=4,
        min=1,
        max=16,
        description="Sampled final render with anti-aliasing: this many consecutive samples "
        "of a pixel share one camera ray through the pixel filter and light its surface "
        "point each their own way; the same image in the end, reached in less time where "
        "lighting is noisier than edges (1: a camera ray per sample, as Cycles). A "
        "mirror-like GGX surface (roughness below about 0.2) always takes a camera ray per "
        "sample: its noise is its highlight across the pixel",
    )
    use_adaptive_sampling: BoolProperty(
        name="Adaptive Sampling",
        default=True,
        description="Sampled final render: pixels whose noise has fallen below the Noise "
        "Threshold stop taking samples, so the time goes where the image is noisy (as Cycles' "
        "Adaptive Sampling); files made before it open with it off",
    )
    adaptive_threshold: FloatProperty(
        name="Noise Threshold",
        default=0.01,
        min=0.0,
        max=1.0,
        soft_min=0.001,
        step=0.1,
        precision=4,
        description="Adaptive sampling: the noise a pixel may keep, as Cycles' Noise Threshold "
        "(lower: less noise, more time); pixels take at least min(16 / threshold^0.3, "
        "samples / 4) samples first; 0: every pixel takes every sample",
    )
    fixed_launch_split: BoolProperty(
        name="Fixed Launch Split",
        default=False,
        description="Split F12 into device launches by a fixed plan instead of by measured "
        "times, so re-renders on the same device are bit-identical (for farms that compare "
        "frames); slightly slower progress updates",
    )
    seed: IntProperty(
        name="Seed",
        default=0,
        min=0,
        description="Randomisation of the low-discrepancy points of the virtual lights and of "
        "the Sampled final render",
    )

    @classmethod
    def register(cls) -> None:
        bpy.types.Scene.btf_render = PointerProperty(type=cls, name="BTF Render")

    @classmethod
    def unregister(cls) -> None:
        del bpy.types.Scene.btf_render


classes = (BTFRenderSettings,)
register, unregister = bpy.utils.register_classes_factory(classes)

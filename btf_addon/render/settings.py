"""The engine's render settings as plain values: what ``scene.btf_render`` holds in Blender,
what the CLI overrides, what the render drivers read. One vocabulary everywhere: the enum
members are named exactly as the Blender EnumProperty identifiers (blender/render_settings.py),
so ``Lighting[prop.lighting]`` and ``member.name`` convert both ways without tables."""

from __future__ import annotations

import enum
from dataclasses import dataclass, fields, replace


class Lighting(enum.Enum):
    """Where the light comes from."""

    ENVIRONMENT = 0  # the World's environment as importance-sampled virtual lights
    HEADLIGHT = 1  # one light from the viewer (fast material checks)


class FinalMode(enum.Enum):
    """How F12 uses the World."""

    VIRTUAL = 0  # exactly the viewport's N virtual lights: deterministic
    SAMPLED = 1  # the World sampled continuously with MIS, path tracing: noise, no approximation


@dataclass(frozen=True)
class RenderSettings:
    """Defaults equal the Blender properties' defaults (a test compares them)."""

    lights_total: int = 256  # N virtual lights
    lights_per_redraw: int = 5  # K lights added per viewport redraw
    progressive: bool = True
    lighting: Lighting = Lighting.ENVIRONMENT
    final_mode: FinalMode = FinalMode.VIRTUAL
    max_bounces: int = 4
    samples: int = 64  # samples per pixel of the Sampled final render
    seed: int = 0

    @property
    def sampled(self) -> bool:
        """Whether F12 path-traces: the Sampled mode under the World (a headlight is one
        deterministic light, so it always renders like Virtual Lights)."""
        return self.final_mode is FinalMode.SAMPLED and self.lighting is Lighting.ENVIRONMENT

    @classmethod
    def from_properties(cls, props) -> RenderSettings:
        """From any object with the same attribute names (``scene.btf_render``); enum
        properties arrive as their identifiers."""
        values = {f.name: getattr(props, f.name) for f in fields(cls)}
        values["lighting"] = Lighting[values["lighting"]]
        values["final_mode"] = FinalMode[values["final_mode"]]
        return cls(**values)

    def to_properties(self, props) -> None:
        """Write every value onto ``props`` (enums as their identifiers)."""
        for f in fields(self):
            value = getattr(self, f.name)
            setattr(props, f.name, value.name if isinstance(value, enum.Enum) else value)

    def with_overrides(self, **overrides) -> RenderSettings:
        """A copy with the given values replaced; ``None`` means "keep"."""
        return replace(self, **{k: v for k, v in overrides.items() if v is not None})

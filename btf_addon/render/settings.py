"""The engine's render settings as plain values: what ``scene.btf_render`` holds in Blender,
what the CLI overrides, what the render drivers read. One vocabulary everywhere: the enum
members are named exactly as the Blender EnumProperty identifiers (blender/render_settings.py),
so ``Lighting[prop.lighting]`` and ``member.name`` convert both ways without tables."""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass, fields, replace

from .pixel_filter import PixelFilter

#: Fields that live on the scene's film (``scene.cycles``), not on ``scene.btf_render``.
FILM_FIELDS = ("pixel_filter", "filter_width")


def blender_float(value: float) -> float:
    """``value`` as a Blender FloatProperty holds it (float32): what a scene reads back, so a
    default that float32 cannot hold exactly (0.01) is written as this to compare equal."""
    return struct.unpack("f", struct.pack("f", value))[0]


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
    # F12 converges to the true image by default; Virtual Lights stays for viewport-matching
    # previews (docs/accuracy.md measures both). Files saved before it keep 'VIRTUAL'.
    final_mode: FinalMode = FinalMode.SAMPLED
    max_bounces: int = 4
    samples: int = 64  # samples per pixel of the Sampled final render
    seed: int = 0
    # Anti-aliasing: samples spread over the pixel filter's footprint (F12 and the viewport's
    # per-pass jitter). False: every ray through the pixel centre, as files saved before it.
    use_antialiasing: bool = True
    aa_samples: int = 16  # subpixel positions of the Virtual Lights F12 (lights split over them)
    # F12's launches split by a fixed plan instead of by measured times: frames bit-identical
    # between runs on one device, for farms that diff frames (render/launch.py).
    fixed_launch_split: bool = False
    # The Sampled mode continues paths from measured BTFs by their sampling tables
    # (core/sampling/btf_importance.py) instead of cosine sampling alone: the same image in the
    # limit,
    # less noise on sharp lobes, ≈ 10 % more time per sample (docs/accuracy.md).
    btf_importance_sampling: bool = True
    # The Sampled mode's indirect light per sample is scaled so that no channel exceeds this
    # (Cycles' Clamp Indirect, whose default it shares; 0: off, unbiased): fireflies become a
    # small, stated bias (docs/accuracy.md).
    clamp_indirect: float = 10.0
    # The Sampled mode's consecutive samples of a pixel that share one camera ray through the
    # pixel filter (1: a ray each, as files saved before it): the same image in the limit,
    # reached sooner (docs/accuracy.md, "Samples per camera ray").
    samples_per_camera_ray: int = 4
    # Adaptive sampling of the Sampled mode (Cycles' Noise Threshold, its meaning and defaults;
    # render/adaptive.py): pixels whose noise estimate falls below the threshold stop taking
    # samples. Off in files saved before it, which render as they did.
    use_adaptive_sampling: bool = True
    adaptive_threshold: float = blender_float(0.01)
    pixel_filter: str = "BLACKMAN_HARRIS"  # scene.cycles.pixel_filter_type where Cycles is on
    filter_width: float = 1.5  # pixels, scene.cycles.filter_width

    def film(self) -> PixelFilter | None:
        """The pixel filter the samples follow; None: pixel centres (anti-aliasing off)."""
        if not self.use_antialiasing:
            return None
        return PixelFilter(self.pixel_filter, self.filter_width)

    @property
    def noise_threshold(self) -> float:
        """The Noise Threshold the Sampled render stops pixels at; 0: adaptive sampling off."""
        return self.adaptive_threshold if self.use_adaptive_sampling else 0.0

    @property
    def sampled(self) -> bool:
        """Whether F12 path-traces: the Sampled mode under the World (a headlight is one
        deterministic light, so it always renders like Virtual Lights)."""
        return self.final_mode is FinalMode.SAMPLED and self.lighting is Lighting.ENVIRONMENT

    @classmethod
    def from_properties(cls, props) -> RenderSettings:
        """From any object with the same attribute names (``scene.btf_render``); enum
        properties arrive as their identifiers."""
        values = {f.name: getattr(props, f.name) for f in fields(cls) if f.name not in FILM_FIELDS}
        values["lighting"] = Lighting[values["lighting"]]
        values["final_mode"] = FinalMode[values["final_mode"]]
        return cls(**values)

    @classmethod
    def from_scene(cls, scene) -> RenderSettings:
        """``scene.btf_render`` plus the film filter Cycles keeps on ``scene.cycles`` (when the
        Cycles add-on is enabled; else Blender's default, Blackman-Harris 1.5 px)."""
        settings = cls.from_properties(scene.btf_render)
        cycles = getattr(scene, "cycles", None)
        filter_type = getattr(cycles, "pixel_filter_type", None)
        if filter_type is None:
            return settings
        return settings.with_overrides(
            pixel_filter=str(filter_type), filter_width=float(cycles.filter_width)
        )

    def to_properties(self, props) -> None:
        """Write every value onto ``props`` (enums as their identifiers; the film filter stays
        on the scene's film)."""
        for f in fields(self):
            if f.name in FILM_FIELDS:
                continue
            value = getattr(self, f.name)
            setattr(props, f.name, value.name if isinstance(value, enum.Enum) else value)

    def with_overrides(self, **overrides) -> RenderSettings:
        """A copy with the given values replaced; ``None`` means "keep"."""
        return replace(self, **{k: v for k, v in overrides.items() if v is not None})

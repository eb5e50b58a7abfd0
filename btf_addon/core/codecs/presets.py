"""Synthetic BTF presets by name, with typed parameters (the ``synth`` command's list)."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from ..model import BTF
from . import microgeometry
from .analytic import GGXBTF, LambertianBTF, PrincipledBTF

PRESETS: dict[str, Callable[..., BTF]] = {
    "lambertian": LambertianBTF,
    "ggx": GGXBTF,
    "principled": PrincipledBTF,
    "woven": microgeometry.woven,
    "leather": microgeometry.leather,
}


def preset_parameters(name: str) -> dict[str, Any]:
    """Parameter name → default value for a preset."""
    sig = inspect.signature(PRESETS[name])
    return {k: p.default for k, p in sig.parameters.items()}


def make_preset(name: str, **params: Any) -> BTF:
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
    known = preset_parameters(name)
    unknown = set(params) - set(known)
    if unknown:
        raise ValueError(
            f"preset {name!r} has no parameter {', '.join(sorted(unknown))}; "
            f"its parameters: {', '.join(known)}"
        )
    return PRESETS[name](**params)

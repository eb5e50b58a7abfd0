"""Materials without BTF settings → the analytic BTF that renders them.

The shader linked to the active Material Output's Surface decides: Principled BSDF →
``PrincipledBTF`` (GGX Cook-Torrance + Fujii Oren-Nayar, docs/conventions.md); Diffuse BSDF →
``LambertianBTF``; Glossy BSDF with GGX → ``GGXBTF`` (both exactly Cycles' closures;
Multiscatter GGX is rendered single-scatter, a few % darker at high roughness). Anything
else, and materials without nodes, render from the viewport display settings (colour,
roughness, metallic) with a message. Inputs driven by links (textures) render at the input's
own value, with a message: only BTF materials carry spatial variation here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.codecs.analytic import GGXBTF, LambertianBTF, PrincipledBTF
from ...core.model import BTF

#: Principled BSDF inputs → PrincipledBTF parameters (inputs Blender versions lack are skipped).
PRINCIPLED_INPUTS = {
    "Base Color": "base_color",
    "Roughness": "roughness",
    "Metallic": "metallic",
    "Diffuse Roughness": "diffuse_roughness",  # Blender 4.3+
}


@dataclass(frozen=True)
class AnalyticKey:
    """One analytic BTF's class and parameters (rounded to 6 decimals, so that float noise in
    Blender's sockets does not make a new BTF)."""

    class_name: str  # the BTF class, e.g. "PrincipledBTF"
    params: tuple[tuple[str, tuple[float, ...]], ...]  # sorted by parameter name

    @classmethod
    def of(cls, btf_class: type, params: dict) -> AnalyticKey:
        rounded = ((k, tuple(np.round(np.atleast_1d(v), 6))) for k, v in params.items())
        return cls(btf_class.__name__, tuple(sorted(rounded)))


# One BTF object per distinct setting: the GPU back ends upload its tables once.
_cache: dict[AnalyticKey, BTF] = {}


def _cached(cls, **params) -> BTF:
    key = AnalyticKey.of(cls, params)
    if key not in _cache:
        _cache[key] = cls(**params)
    return _cache[key]


def surface_node(material):
    """The node linked to the active Material Output's Surface input, or None."""
    tree = material.node_tree
    if tree is None:
        return None
    outputs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    output = next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)
    if output is None or not output.inputs["Surface"].is_linked:
        return None
    return output.inputs["Surface"].links[0].from_node


def _value(material, node, socket_name: str, messages: list[str]):
    socket = node.inputs[socket_name]
    if socket.is_linked:
        message = (
            f"material {material.name!r}: {node.name} {socket_name} is driven by nodes; "
            "rendered with the input's own value (only BTF materials carry textures here)"
        )
        if message not in messages:
            messages.append(message)
    value = socket.default_value
    return tuple(value)[:3] if socket.type == "RGBA" else float(np.clip(value, 0.0, 1.0))


def _principled(material, node, messages: list[str]) -> dict:
    params = {
        key: _value(material, node, name, messages)
        for name, key in PRINCIPLED_INPUTS.items()
        if name in node.inputs
    }
    ior, level = node.inputs.get("IOR"), node.inputs.get("Specular IOR Level")
    if ior is not None:
        f0 = ((ior.default_value - 1.0) / (ior.default_value + 1.0)) ** 2
        # Blender's Specular IOR Level 0.5 leaves F0 as the IOR gives; 1.0 doubles it.
        f0 *= 2.0 * (level.default_value if level is not None else 0.5)
        params["specular_f0"] = float(np.clip(f0, 0.0, 1.0))
    return params


def analytic_btf(material, messages: list[str]) -> BTF:
    """The analytic BTF that renders ``material`` (a ``bpy.types.Material``; None: Blender's
    default grey). Simplifications are appended to ``messages``."""
    if material is None:
        return _cached(PrincipledBTF, base_color=(0.8, 0.8, 0.8), roughness=0.5)
    node = surface_node(material)
    kind = node.bl_idname if node is not None else None
    if kind == "ShaderNodeBsdfPrincipled":
        return _cached(PrincipledBTF, **_principled(material, node, messages))
    if kind == "ShaderNodeBsdfDiffuse":
        if _value(material, node, "Roughness", messages) > 0.0:
            messages.append(
                f"material {material.name!r}: Diffuse BSDF roughness is rendered as 0 "
                "(Lambertian); a Principled BSDF's Diffuse Roughness is rendered"
            )
        return _cached(LambertianBTF, albedo=_value(material, node, "Color", messages))
    # Blender 4+ creates the Glossy BSDF as ShaderNodeBsdfAnisotropic.
    glossy = kind in {"ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic"}
    if glossy and node.distribution in {"GGX", "MULTI_GGX"}:
        if "Anisotropy" in node.inputs and node.inputs["Anisotropy"].default_value != 0.0:
            messages.append(f"material {material.name!r}: anisotropy is rendered as 0")
        return _cached(
            GGXBTF,
            albedo=_value(material, node, "Color", messages),
            roughness=_value(material, node, "Roughness", messages),
        )
    if node is not None:
        messages.append(
            f"material {material.name!r}: surface shader {node.name!r} is not rendered by the "
            "BTF engine; its viewport display colour, roughness and metallic are used"
        )
    return _cached(
        PrincipledBTF,
        base_color=tuple(material.diffuse_color)[:3],
        roughness=float(material.roughness),
        metallic=float(material.metallic),
    )

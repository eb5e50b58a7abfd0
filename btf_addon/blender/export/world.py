"""The World's lighting as a core ``Environment``.

Supported node setups (what Blender's own "Environment Texture" workflow creates):
Background ← [Environment Texture ← [Mapping ← [Texture Coordinate]]] → World Output, with the
Background's Strength and the Mapping's Z rotation honoured. A plain World colour (no nodes, or
an unlinked Background colour) is a constant environment. Anything else gives a message that
says what was not understood and a constant fallback, never an exception.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...core.colour import srgb_decode
from ...core.sampling.envmap import Environment
from .. import compat
from .world_cache import cached_environment, cached_pixels

BLACK = (0.0, 0.0, 0.0)


def _linked_node(socket):
    return socket.links[0].from_node if socket.is_linked and socket.links else None


def _active_output(tree):
    outputs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld"]
    for node in outputs:
        if node.is_active_output:
            return node
    return outputs[0] if outputs else None


def image_pixels(image) -> np.ndarray:
    """A Blender image → (H, W, 3) float32 scene-linear, row 0 at the top; from the disk when
    this file was read before with the same settings (world_cache.py)."""
    return cached_pixels(image, lambda: _read_pixels(image))


def _read_pixels(image) -> np.ndarray:
    """image_pixels from Blender: the file decoded (on first use) and copied out."""
    w, h = image.size
    if w == 0 or h == 0:
        import bpy  # only here: the path a farm is missing, not the datablock's name

        path = bpy.path.abspath(image.filepath, library=image.library) or "(no file path)"
        raise ValueError(f"World image {image.name!r}: {path} is missing or unreadable")
    channels = image.channels
    buf = np.empty(w * h * channels, dtype=np.float32)
    image.pixels.foreach_get(buf)
    rgb = buf.reshape(h, w, channels)[::-1, :, :3]  # Blender stores the bottom row first
    if rgb.shape[2] == 1:
        rgb = np.repeat(rgb, 3, axis=2)
    if not image.is_float and image.colorspace_settings.name == "sRGB":
        rgb = srgb_decode(rgb)
    return np.ascontiguousarray(rgb, dtype=np.float32)


def _mapping_rotation_z(mapping, messages: list[str]) -> float:
    rot = mapping.inputs["Rotation"]
    if rot.is_linked or mapping.inputs["Location"].is_linked or mapping.inputs["Scale"].is_linked:
        messages.append("World Mapping node inputs are linked; only constant rotation is used")
    x, y, z = rot.default_value
    if abs(x) > 1e-6 or abs(y) > 1e-6:
        messages.append("World Mapping X/Y rotation is ignored; only Z rotation is supported")
    if any(abs(v) > 1e-6 for v in mapping.inputs["Location"].default_value):
        messages.append("World Mapping location is ignored")
    if mapping.vector_type == "TEXTURE":  # the inverse transform
        return -z
    return z


class WorldEnvironment(NamedTuple):
    environment: Environment
    messages: list[str]  # every simplification or fallback, for the UI


def environment_from_world(world) -> WorldEnvironment:
    """``world``: a ``bpy.types.World`` or None. Never raises for an unsupported setup."""
    messages: list[str] = []
    if world is None:
        return WorldEnvironment(Environment.constant(BLACK), ["the scene has no World: black"])
    # Blender < 5 can switch a World's nodes off (then World.color lights the scene); Blender 5
    # always uses the nodes and deprecates the switch, so it is only read on older versions.
    nodes_off = compat.world_nodes_switched_off(world)
    if nodes_off or world.node_tree is None:
        return WorldEnvironment(Environment.constant(tuple(world.color)), messages)
    output = _active_output(world.node_tree)
    background = _linked_node(output.inputs["Surface"]) if output else None
    if background is None or background.bl_idname != "ShaderNodeBackground":
        messages.append("World output is not fed by a Background node: using a black world")
        return WorldEnvironment(Environment.constant(BLACK), messages)
    strength_socket = background.inputs["Strength"]
    strength = float(strength_socket.default_value)
    if strength_socket.is_linked:
        messages.append("linked Background strength is not supported: using 1.0")
        strength = 1.0
    color_socket = background.inputs["Color"]
    fallback = Environment.constant(tuple(color_socket.default_value)[:3], strength)
    texture = _linked_node(color_socket)
    if texture is None:
        return WorldEnvironment(fallback, messages)
    if texture.bl_idname != "ShaderNodeTexEnvironment" or texture.image is None:
        messages.append(
            f"World colour comes from {texture.bl_label!r}, not an Environment "
            "Texture with an image: using the Background colour"
        )
        return WorldEnvironment(fallback, messages)
    if texture.projection != "EQUIRECTANGULAR":
        messages.append("mirror-ball projection is not supported: using the Background colour")
        return WorldEnvironment(fallback, messages)
    rotation = 0.0
    mapping = _linked_node(texture.inputs["Vector"])
    if mapping is not None:
        if mapping.bl_idname == "ShaderNodeMapping":
            rotation = _mapping_rotation_z(mapping, messages)
        elif mapping.bl_idname != "ShaderNodeTexCoord":
            messages.append(f"{mapping.bl_label!r} before the Environment Texture is ignored")
    image = texture.image
    try:
        env = cached_environment(
            image,
            strength,
            rotation,
            lambda: Environment(image_pixels(image), strength=strength, rotation_z_rad=rotation),
        )
    except (ValueError, RuntimeError) as exc:  # the image's pixels: missing or unreadable
        messages.append(f"environment image unusable ({exc}): using the Background colour")
        return WorldEnvironment(fallback, messages)
    if env.nonfinite_count:
        messages.append(f"{env.nonfinite_count} NaN/Inf pixels in {texture.image.name!r} set to 0")
    return WorldEnvironment(env, messages)

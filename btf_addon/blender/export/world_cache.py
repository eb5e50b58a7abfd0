"""The World image's pixels kept on disk between sessions, and the environment made of them.
Reading them from Blender decodes the file first (forest.exr, 1024 × 512: 13-20 ms) and then
copies them out (2-26 ms), in every new Blender process: a tenth of a small scene's F12 (a
render farm's every frame, an F12 after a material tweak). Cleaning them, weighing them and
building the final render's sampling tables from them (core/sampling/envmap.py) cost another
~25 ms of such an F12 on forest.exr, so the built environment is kept too
(``cached_environment``: ``Environment.state`` under the image's key and the Background's
strength, read back by ``Environment.from_state``; ``Environment.valid_state`` checks it).

Only a clean image read from a file is kept: its key is the file (real path, size,
modification time in nanoseconds), the settings that change what Blender decodes (colour
space, alpha mode, half precision), Blender's version and the source text of world.py (the
reading code); an environment's key adds the strength and the source text of envmap.py (the
code that builds it). Anything else is read from Blender each time: a packed, generated,
tiled or movie image, one edited in Blender and not saved (``is_dirty``), a file that cannot
be stat'ed (its error then comes from Blender, as before). The file is not opened to key it:
a file rewritten within the same nanosecond and size would be missed (no editor does that).

Files: core/npz_store.py (the zip's CRC-32 checked on every read; a damaged file is read
again from Blender and replaced),
at most 1 GiB (a 4096 × 2048 map takes 100 MB), least recently used first out. Where: in
Blender the extension's user directory; else ``BTF_WORLD_CACHE`` (``off`` turns it off),
else ``$XDG_CACHE_HOME/btf_materials/world``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable

import numpy as np

from ...core.npz_store import NpzStore
from ...core.sampling import envmap
from ...core.sampling.envmap import Environment
from ...core.sampling.table_cache import table_key

STORE = NpzStore("World image cache", "BTF_WORLD_CACHE", "world", 2**30)


def image_identity(image) -> dict | None:
    """What the pixels of ``image`` (a ``bpy.types.Image``) depend on, without loading it;
    None when it cannot be known that way (module docstring)."""
    import bpy

    if image.source != "FILE" or image.packed_file is not None or image.is_dirty:
        return None
    path = bpy.path.abspath(image.filepath, library=image.library)
    try:
        info = os.stat(path)
    except (OSError, ValueError):
        return None
    return {
        "path": os.path.realpath(path),
        "bytes": info.st_size,
        "mtime_ns": info.st_mtime_ns,
        "colorspace": image.colorspace_settings.name,
        "alpha_mode": image.alpha_mode,
        "half": bool(image.use_half_precision),
        "blender": bpy.app.version_string,
    }


def _valid(arrays: dict) -> bool:
    rgb = arrays.get("rgb")
    return rgb is not None and rgb.dtype == np.float32 and rgb.ndim == 3 and rgb.shape[2] == 3


def cached_pixels(image, read: Callable[[], np.ndarray]) -> np.ndarray:
    """``read()`` (world.py: the image's (H, W, 3) float32 pixels), from the disk when this
    image was read before."""
    identity = image_identity(image)
    if identity is None:
        return read()
    key = table_key([], identity, [sys.modules[read.__module__]])
    arrays = STORE.load(key, _valid)
    if arrays is not None:
        return arrays["rgb"]
    rgb = read()
    STORE.store(key, {"rgb": rgb})
    return rgb


def cached_environment(
    image, strength: float, rotation: float, build: Callable[[], Environment]
) -> Environment:
    """``build()`` (world.py: the Environment of ``image``'s pixels at ``strength``, turned by
    ``rotation``), from the disk when this image was built at this strength before. On a first
    build the final render's tables are built here too (``Environment.state``), so that the
    next session finds them: ~10 ms once per map and strength."""
    identity = image_identity(image)
    if identity is None:
        return build()
    params = {**identity, "strength": float(strength), "kept": "environment"}
    key = table_key([], params, [sys.modules[build.__module__], envmap])
    state = STORE.load(key, Environment.valid_state)
    if state is not None:
        return Environment.from_state(state, rotation)
    environment = build()
    state = environment.state()
    # A map whose environment would take over a quarter of the folder (its state is ~1.7 × its
    # pixels' bytes: maps beyond ~6000 × 3000) is built each session, not pushing the rest out.
    if sum(array.nbytes for array in state.values()) <= STORE.cap_bytes // 4:
        STORE.store(key, state)
    return environment

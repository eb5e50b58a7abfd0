"""The World prefiltered for glossy playback: the light bake's analytic objects read their
unshadowed reflection of the World through it (filtered importance sampling, Křivánek and
Colbert 2008: each of a few directions drawn from the material's lobe reads the World averaged
over that direction's share of the sphere, so a handful of directions gives a converged lobe).

Averaging blurs: a small bright source (a sun, sky through leaves) would spread over the
filter's area and its highlight with it. So the light above SUN_RATIO × the map's mean
luminance (the final render's sun threshold, core/sampling/envmap.py) is taken out of the map
first and summed into at most MAX_SUNS directional lights (the map's blocks that hold any, each
at its light-weighted mean direction with its total power), which playback evaluates exactly;
the pyramid holds the rest (docs/accuracy.md "The light bake played back" measures both).

Levels: level 0 is the World's map without its suns, halved while wider than MAX_WIDTH; level
k is level k − 1 averaged over blocks of 2 × 2 pixels (every column and row once; odd sizes
give one block of 3), each pixel weighted by its solid angle (sin θ of its row), down to 1 × 1.
They are stacked top to bottom in one (rows, W, 4) float32 array, level k at rows
[offset_k, offset_k + h_k), columns [0, w_k), with w_k = max(W >> k, 1) and
h_k = max(H >> k, 1): the GPU shader (shaders/lobe_lib.glsl) and the OpenCL kernel
(kernels/include/btf_lobe.h) find a level from W, H and k alone. One more row
holds the suns: texel 2i = (direction in the map's frame, xyz; texel 0's w: how many), texel
2i + 1 = (power, rgb: radiance × solid angle). bpy- and GL-free.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .envmap import LUMINANCE, SUN_RATIO

#: Directions per pixel and frame of an analytic object's unshadowed light (the method:
#: kernels/include/btf_lobe.h; the drawer's ``lobe_samples``, render_baked's), a draw-time
#: value, not a build define; frames continue the sequence, so a still head's image keeps
#: converging. docs/accuracy.md "The light bake played back" measures 8 to 64.
LOBE_SAMPLES = 32
#: Levels coarser than the one whose pixels a direction's share of the sphere covers. The
#: paper adds 1 to hide the pyramid's square blocks; measured on the demo's glossy sphere, 1
#: blurs its highlights (23 % off F12 against 8.7 % with 0, 16 directions, 16 frames).
LOBE_LOD_BIAS = 0


#: Directional lights the suns are summed into at most (each costs a pixel one evaluation).
MAX_SUNS = 64
#: The finest blocks the suns are summed over: this many across the map (5.6° each).
SUN_BLOCKS = 64
#: Level 0's widest: a lobe drawn 32 times reads finer levels only where it is narrower than
#: about 1° (roughness < 0.1), and a 4096 × 2048 map's pyramid would be 256 MiB of textures.
MAX_WIDTH = 2048


def lobe_defines() -> dict[str, int]:
    """The build define both back ends read the bias by (an integer: no double literal
    reaches an OpenCL device without doubles)."""
    return {"LOBE_LOD_BIAS": LOBE_LOD_BIAS}


@dataclass(frozen=True, eq=False)
class WorldPyramid:
    """``rgba``: the stacked levels and the suns' row; ``levels``: how many; ``width``,
    ``height``: level 0's; ``suns``: how many directional lights the suns' row holds."""

    rgba: np.ndarray
    levels: int
    width: int
    height: int
    suns: int

    @property
    def nbytes(self) -> int:
        return int(self.rgba.nbytes)


def level_size(width: int, height: int, k: int) -> tuple[int, int]:
    return max(width >> k, 1), max(height >> k, 1)


def level_count(width: int, height: int) -> int:
    """Levels until both sides are 1 pixel."""
    return max(int(width), int(height)).bit_length()


def _block_starts(n: int, m: int) -> np.ndarray:
    """Where each of ``m`` output pixels' block starts among ``n`` inputs (blocks of n // m or
    one more, in order)."""
    return (np.arange(m) * n) // m


def _halve(
    level: np.ndarray, sin_rows: np.ndarray, w: int, h: int
) -> tuple[np.ndarray, np.ndarray]:
    """Level ``level`` (solid-angle weights ``sin_rows`` per row) averaged to (h, w)."""
    rows, cols = level.shape[:2]
    weighted = level * sin_rows[:, None, None]
    col_starts, row_starts = _block_starts(cols, w), _block_starts(rows, h)
    summed = np.add.reduceat(np.add.reduceat(weighted, col_starts, axis=1), row_starts, axis=0)
    col_counts = np.diff(np.append(col_starts, cols))
    weight = np.add.reduceat(sin_rows, row_starts)[:, None] * col_counts[None, :]
    out = summed / np.maximum(weight, 1e-30)[..., None]
    return out, np.add.reduceat(sin_rows, row_starts) / np.diff(np.append(row_starts, rows))


def world_pyramid(env) -> WorldPyramid:
    """The pyramid of ``env`` (core/sampling/envmap.py Environment), built once per Environment
    (kept on it: the World's map never changes inside one Environment). Level 0 is the map
    halved until at most MAX_WIDTH wide, so the pyramid takes at most 2 × MAX_WIDTH² × 16
    bytes + one row (64 MiB) on the GPU whatever the map; on the host, while it is built,
    float32 working copies of about 32 bytes per pixel of the map (transient: 1 GiB for an
    8192 × 4096 map, whose own radiance Blender already holds at 12 to 16)."""
    cached = getattr(env, "_world_pyramid", None)
    if cached is not None:
        return cached
    base = np.array(env.rgba32()[..., :3], dtype=np.float32)  # a copy: the suns leave it
    height, width = base.shape[:2]
    theta = (np.arange(height) + 0.5) / height * np.pi
    sin_rows = np.maximum(np.sin(theta), 1e-6).astype(np.float32)
    sun_dirs, sun_power = _take_suns(base, sin_rows, env.mean_luminance)  # the full map's
    while width > MAX_WIDTH:  # a larger map's finest level is this wide (the bound above)
        width, height = level_size(width, height, 1)
        base, sin_rows = _halve(base, sin_rows, width, height)
    levels = level_count(width, height)
    parts, level = [base], base
    for k in range(1, levels):
        w, h = level_size(width, height, k)
        level, sin_rows = _halve(level, sin_rows, w, h)
        parts.append(level)
    total = sum(p.shape[0] for p in parts)
    # the suns' row: 2 texels each, so a map narrower than 2 · MAX_SUNS keeps fewer
    suns = min(len(sun_dirs), width // 2)
    if suns < len(sun_dirs):
        keep = np.argsort(-(sun_power @ LUMINANCE))[:suns]
        sun_dirs, sun_power = sun_dirs[keep], sun_power[keep]
    rgba = np.zeros((total + 1, width, 4), np.float32)
    row = 0
    for p in parts:
        rgba[row : row + p.shape[0], : p.shape[1], :3] = p
        rgba[row : row + p.shape[0], : p.shape[1], 3] = 1.0
        row += p.shape[0]
    rgba[total, 0 : 2 * suns : 2, :3] = sun_dirs
    rgba[total, 1 : 2 * suns : 2, :3] = sun_power
    rgba[total, 0, 3] = suns
    pyramid = WorldPyramid(rgba, levels, width, height, suns)
    env._world_pyramid = pyramid
    return pyramid


def _take_suns(base: np.ndarray, sin_rows: np.ndarray, mean: float):
    """Take the light above SUN_RATIO × ``mean`` (the map's mean luminance over the sphere,
    Environment.mean_luminance) out of map ``base`` (in place) and return (the suns'
    directions in the map's frame (S, 3), their power (S, 3)): the light taken out summed per
    block of the map, blocks doubling in size until at most MAX_SUNS hold any."""
    height, width = base.shape[:2]
    luminance = base @ LUMINANCE.astype(np.float32)
    no_suns = np.zeros((0, 3))
    if not mean > 0.0:
        return no_suns, no_suns
    cap = SUN_RATIO * mean
    bright = luminance > cap
    if not bright.any():
        return no_suns, no_suns
    rows, cols = np.nonzero(bright)
    del bright
    pixels = base[rows, cols].astype(np.float64)
    keep = cap / luminance[rows, cols].astype(np.float64)  # above cap > 0: no division by 0
    solid = (2 * np.pi / width) * (np.pi / height) * sin_rows.astype(np.float64)
    power = pixels * (1.0 - keep)[:, None] * solid[rows, None]  # what leaves the map
    base[rows, cols] = pixels * keep[:, None]
    theta = (rows + 0.5) / height * np.pi
    phi = np.pi - 2 * np.pi * (cols + 0.5) / width  # as envmap.directions_from_image_coords
    dirs = np.column_stack(
        [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]
    )
    block = max(width // SUN_BLOCKS, 1)
    while True:
        keys = (rows // block) * (width // block + 1) + cols // block
        groups, index = np.unique(keys, return_inverse=True)
        if len(groups) <= MAX_SUNS:
            break
        block *= 2
    weight = power @ LUMINANCE
    sun_power = np.zeros((len(groups), 3))
    sun_dirs = np.zeros((len(groups), 3))
    np.add.at(sun_power, index, power)
    np.add.at(sun_dirs, index, dirs * weight[:, None])
    sun_dirs /= np.maximum(np.linalg.norm(sun_dirs, axis=1, keepdims=True), 1e-300)
    return sun_dirs, sun_power

"""Environment lighting from an equirectangular HDR image: importance sampling and virtual lights.

Orientation matches Blender's Environment Texture exactly (Cycles'
``direction_to_equirectangular``): for a world direction d (Z up) the texture is read at
s = (π − atan2(d_y, d_x)) / 2π across and at elevation asin(d_z) up, so the image centre faces
+X, s grows towards −Y, and the top row is the zenith. A Mapping node's Z rotation γ turns the
lookup vector (m = R_z(γ)·d), so the world sees the map turned by −γ.

The image is (H, W, 3) with row 0 at the top, as files store it. Sampling density: pixel
luminance × sin θ (θ from the zenith at the pixel's centre row), piecewise constant in the image
plane (marginal over rows, conditionals over columns); continuous positions inside a pixel.
Solid-angle pdf = pdf_image / (2π² sin θ).
"""

from __future__ import annotations

import functools
import logging
import threading
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .sequences import sobol_2d

log = logging.getLogger(__name__)

#: Rec.709 luminance (Blender's default scene-linear role).
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
#: sin θ never goes below this in a pdf: keeps pole samples finite.
MIN_SIN_THETA = 1e-9
#: A map's sun (``Environment.sun_tables``): its pixels at least this many times its mean luminance…
SUN_RATIO = 16.0
#: …holding at least this share of its light above the mean…
SUN_MIN_SHARE = 0.1
#: …in at most this fraction of its pixels (a compact source, not a bright half of the sky).
SUN_MAX_PIXELS = 0.01
#: A map with a sun gets the lobe window (``Environment.lobe_window``) where the rest of its
#: light is patchy: at least WINDOW_MIN_SHARE of the compensated weight beside the sun lies in
#: pixels at least WINDOW_RATIO times the mean luminance (forest.exr: 0.70, city.exr: 0.40).
WINDOW_RATIO = 4.0
WINDOW_MIN_SHARE = 0.6
#: The lobe window's block map (``lobe_window_table``) has at most this many rows of blocks…
WINDOW_BLOCK_ROWS = 128
#: …of at most this many pixels a side (kernels/include/btf_env_window.h WINDOW_BLOCK_MAX): a
#: map more than 8192 pixels tall gets no window.
WINDOW_MAX_BLOCK = 64


class SamplingTables(NamedTuple):
    """A piecewise-constant distribution over the map's pixels: a row by its marginal, then a
    column within it (each pixel's probability is row_pdf[r] · col_pdf[r, c])."""

    row_pdf: np.ndarray  # (H,) probability of each row
    row_cdf: np.ndarray  # (H + 1,) from 0 to 1
    col_pdf: np.ndarray  # (H, W) probability of each column within its row
    col_cdf: np.ndarray  # (H, W + 1) each row from 0 to 1


class SunTable(NamedTuple):
    """The final render's draws of a map's sun: a pixel k with probability[k] (∝ its
    MIS-compensated weight (L − L̄) · sin θ, as the rest of the map's draws), by its CDF, then
    a point uniformly in it. float32 and int32, as the kernels read them."""

    pixels: np.ndarray  # (K,) flat pixel indices (row · width + column), ascending
    cdf: np.ndarray  # (K + 1,) from 0 to 1
    probability: np.ndarray  # (K,) each pixel's probability
    share: float  # the sun's share of the compensated weight: where the kernels draw it or
    # the rest of the map by this share, the two make mis_tables exactly


class LobeWindowTable(NamedTuple):
    """A table's pixel probabilities summed over blocks of ``block`` × ``block`` pixels
    (partial at the right and bottom edges), laid out as SamplingTables are: each row of
    blocks' probability (row_pdf) and the CDF over its blocks (cdf, (rows, cols + 1)). The
    kernel's lobe-window draws (kernels/render_direct.cl, "1c.") sum a window's blocks row by
    row from it, then pick a pixel inside the drawn block from the table itself. float32, as
    the kernels read them."""

    block: int
    row_pdf: np.ndarray  # (rows,)
    cdf: np.ndarray  # (rows, cols + 1) each row from 0 to 1 (0 throughout an empty row)


def lobe_window_table(tables: SamplingTables) -> LobeWindowTable:
    """``tables``' block sums for the lobe-window draws, from its float32 probabilities
    (row_pdf · col_pdf, what the kernel reads) summed in float64. Blocks are square, as many
    rows of them as WINDOW_BLOCK_ROWS allows: a window the kernel sums is at most that many
    rows, whatever the map's size, and a drawn block's pixels are at most block² to pick from
    (the 4096 × 2048 map: 16 × 16)."""
    h, w = tables.col_pdf.shape
    block = -(-h // WINDOW_BLOCK_ROWS)
    rows, cols = -(-h // block), -(-w // block)
    probability = np.zeros((rows * block, cols * block))
    probability[:h, :w] = tables.col_pdf
    probability[:h, :w] *= np.asarray(tables.row_pdf, dtype=np.float64)[:, None]
    sums = probability.reshape(rows, block, cols, block).sum(axis=(1, 3))
    row_pdf = sums.sum(axis=1)
    cdf = np.zeros((rows, cols + 1))
    np.cumsum(sums, axis=1, out=cdf[:, 1:])
    cdf /= np.where(row_pdf > 0.0, row_pdf, 1.0)[:, None]
    return LobeWindowTable(block, row_pdf.astype(np.float32), cdf.astype(np.float32))


def sampling_tables(weight: np.ndarray) -> SamplingTables:
    """(H, W) non-negative weights with a positive sum → their tables. ``weight`` is consumed
    (normalised in place and kept as col_pdf): a large map's tables cost its size once more."""
    h, w = weight.shape
    weight /= weight.sum()  # normalise first: 1e6-valued maps stay well scaled
    row_mass = weight.sum(axis=1)
    row_cdf = np.concatenate([[0.0], np.cumsum(row_mass)])
    row_cdf /= row_cdf[-1]
    empty = row_mass <= 0
    weight /= np.where(empty, 1.0, row_mass)[:, None]
    weight[empty] = 1.0 / w
    col_cdf = np.empty((h, w + 1))  # filled in place: no concatenated copy of the map's size
    col_cdf[:, 0] = 0.0
    np.cumsum(weight, axis=1, out=col_cdf[:, 1:])
    col_cdf /= col_cdf[:, -1:]
    return SamplingTables(row_mass, row_cdf, weight, col_cdf)


@dataclass
class VirtualLights:
    """N directional lights. direction (N, 3) world, Z up; radiance (N, 3) of the environment in
    that direction; pdf (N,) solid-angle density it was drawn with. A prefix of k lights estimates
    ∫ f(ω) L(ω) dω ≈ (1/k) Σ_{i<k} f(ω_i) L_i / pdf_i."""

    direction: np.ndarray
    radiance: np.ndarray
    pdf: np.ndarray

    def prefix(self, k: int) -> VirtualLights:
        """The first k lights: itself a stratified estimate."""
        return VirtualLights(self.direction[:k], self.radiance[:k], self.pdf[:k])

    def packed(self) -> np.ndarray:
        """(N, 8) float32 rows (direction xyz, 0, radiance/pdf rgb, 0): the layout every GPU back
        end reads (GLSL as two RGBA texels per light, OpenCL as 8 floats per light)."""
        rows = np.zeros((len(self.pdf), 8), dtype=np.float32)
        rows[:, :3] = self.direction
        rows[:, 4:7] = self.radiance / self.pdf[:, None]
        return rows

    def weights(self, k: int | None = None) -> np.ndarray:
        """(k, 3) irradiance carried by each of the first k lights: L_i / (pdf_i · k)."""
        k = len(self.pdf) if k is None else k
        return self.radiance[:k] / (self.pdf[:k, None] * k)

    def irradiance(self, normals: np.ndarray, k: int | None = None) -> np.ndarray:
        """(M, 3) normals → (M, 3) irradiance estimated from the first k lights."""
        k = len(self.pdf) if k is None else k
        cos = np.maximum(np.asarray(normals, dtype=np.float64) @ self.direction[:k].T, 0.0)
        return cos @ self.weights(k)


def _pixels_with(flags: np.ndarray) -> int:
    """How many pixels of (H, W, 3) channel flags have at least one set. The channels or-ed
    one by one: numpy's ``any(axis=-1)`` over an axis of 3 took 7 ms of each F12 on a
    1024 × 512 map with a few negative pixels (forest.exr), this takes under 1."""
    return int(np.count_nonzero(flags[..., 0] | flags[..., 1] | flags[..., 2]))


def _float32(tables: SamplingTables) -> SamplingTables:
    return SamplingTables(*(table.astype(np.float32) for table in tables))


class Environment:
    """An HDR environment (or a constant colour) that can be looked up and sampled."""

    def __init__(self, image: np.ndarray, strength: float = 1.0, rotation_z_rad: float = 0.0):
        image = np.asarray(image)
        if image.ndim == 2:
            image = np.repeat(image[..., None], 3, axis=-1)
        if image.ndim != 3 or image.shape[2] < 3 or min(image.shape[:2]) < 1:
            raise ValueError(f"environment image must be (H, W, 3), got {image.shape}")
        if not np.isfinite(strength) or strength < 0:
            raise ValueError(f"environment strength must be finite and ≥ 0, got {strength!r}")
        if not np.isfinite(rotation_z_rad):
            raise ValueError(f"environment rotation must be finite, got {rotation_z_rad!r}")
        # One copy, cleaned and scaled in place: a large map is held once, not three times
        # (memory model: core/memory.py ENV_PIXEL_BYTES); the values are the same. A clean map
        # (the usual case) costs two reading passes for the checks: every pass over a
        # 1024 × 512 map is milliseconds of each F12's fixed cost. A float32 map (every image
        # Blender or an EXR gives) stays float32: the same values, exactly, in half the memory,
        # and its float32 RGBA texture (rgba32) is then a copy, not a conversion (12 ms of
        # each F12 at 1024 × 512, measured); the luminance weights and tables are float64 either
        # way (numpy computes float32 @ float64 in float64). Other inputs become float64.
        dtype = np.float32 if image.dtype == np.float32 else np.float64
        with np.errstate(invalid="ignore"):  # signalling NaNs in a file: cleaned just below
            radiance = np.array(image[..., :3], dtype=dtype)
        del image
        self.nonfinite_count = self.negative_count = 0
        finite = np.isfinite(radiance)
        if not finite.all():
            self.nonfinite_count = _pixels_with(~finite)
            log.warning("environment: %d NaN/Inf pixels set to 0", self.nonfinite_count)
            radiance[~finite] = 0.0
        del finite
        if radiance.min(initial=0.0) < 0.0:
            self.negative_count = _pixels_with(radiance < 0.0)
            # HDR files often hold tiny negative noise: not worth a warning
            log.debug("environment: %d negative pixels set to 0", self.negative_count)
            np.maximum(radiance, 0.0, out=radiance)
        if strength != 1.0:
            radiance *= float(strength)
        self.radiance = radiance
        self._rgba: np.ndarray | None = None  # rgba32's array, where from_state gave it
        self.height, self.width = self.radiance.shape[:2]
        self.rotation_z_rad = float(rotation_z_rad)
        self._build_distribution()

    def rgba32(self) -> np.ndarray:
        """(H, W, 4) float32 radiance with alpha 1: the texture both GPU back ends upload. An
        Environment read back by ``from_state`` holds it already (its radiance is a view of it)
        and returns that array: callers upload it, never write to it."""
        if self._rgba is not None:
            return self._rgba
        rgba = np.empty((self.height, self.width, 4), dtype=np.float32)
        rgba[..., :3] = self.radiance
        rgba[..., 3] = 1.0
        return rgba

    @classmethod
    def constant(cls, rgb, strength: float = 1.0) -> Environment:
        return cls(np.asarray(rgb, dtype=np.float64).reshape(1, 1, 3), strength)

    def _build_distribution(self) -> None:
        """The luminance weights (∝ L · sin θ), the map's mean and whether it is black. The
        tables are built from the weights on first use (``tables``, ``mis_tables``): F12's
        Sampled mode needs only the compensated ones, the viewport only the plain ones, and
        each build is milliseconds of a frame's fixed cost."""
        self._sin_rows = np.sin(np.pi * (np.arange(self.height) + 0.5) / self.height)
        # The viewport (main thread) and F12 (a render thread) may share one Environment.
        self._tables_lock = threading.Lock()
        # the lobe window's rule (lobe_window), measured by sun_tables where the map has a sun
        self._patchy_share = 0.0
        self._weight: np.ndarray | None = self._luminance_weight()
        total = self._weight.sum()
        # Far below this nothing is visible at all; also covers the all-zero map.
        self.is_black = not (total > 0.0 and np.isfinite(total))
        #: The mean luminance over the sphere (pixels weighted by their solid angle).
        self.mean_luminance = 0.0 if self.is_black else total / (self._sin_rows.sum() * self.width)
        if self.is_black:
            self._weight = np.broadcast_to(self._sin_rows[:, None], self._weight.shape).copy()

    def _luminance_weight(self) -> np.ndarray:
        """L · sin θ per pixel, float64. The luminance in the map's own precision: a float32 map
        times float64 weights made numpy convert the whole map to float64 first (6–32 ms per
        F12 on forest.exr, mostly fresh pages), float32 weights take 3 ms."""
        # contiguous: from_state's radiance is a view into the RGBA texture, and a strided
        # product may round differently; the tables must not depend on where the map came from
        radiance = np.ascontiguousarray(self.radiance)
        luminance = radiance @ LUMINANCE.astype(radiance.dtype)  # ≥ 0: cleaned
        weight = luminance.astype(np.float64, copy=False)
        weight *= self._sin_rows[:, None]
        return weight

    @functools.cached_property
    def tables(self) -> SamplingTables:
        """The plain tables: density ∝ L · sin θ (uniform over the sphere for a black map)."""
        with self._tables_lock:
            weight, self._weight = self._weight, None  # consumed: the tables hold it as col_pdf
            if weight is None:  # another thread's first use got here first
                weight = self._luminance_weight()
                if self.is_black:
                    weight = np.broadcast_to(self._sin_rows[:, None], weight.shape).copy()
            return sampling_tables(weight)

    row_pdf = property(lambda self: self.tables.row_pdf)
    row_cdf = property(lambda self: self.tables.row_cdf)
    col_pdf = property(lambda self: self.tables.col_pdf)
    col_cdf = property(lambda self: self.tables.col_cdf)

    def _excess(self) -> np.ndarray | None:
        """max(L − L̄, 0) · sin θ per pixel (float64), or None where nothing lies above the
        mean (black, or a constant colour)."""
        if self.is_black:
            return None
        with self._tables_lock:  # `tables` normalises the weights in place
            weight = self._weight if self._weight is not None else self._luminance_weight()
            # (L − L̄) · sin θ = L · sin θ − L̄ · sin θ: from the weights, not the radiance
            excess = weight - self.mean_luminance * self._sin_rows[:, None]
        np.maximum(excess, 0.0, out=excess)
        total = excess.sum()
        return excess if total > 0.0 and np.isfinite(total) else None

    @functools.cached_property
    def mis_tables(self) -> SamplingTables:
        """The final render's next-event tables: MIS compensation (Karlík et al. 2019,
        "MIS Compensation: Optimizing Sampling Techniques in Multiple Importance Sampling"):
        density ∝ max(L − L̄, 0) · sin θ, L̄ the map's mean luminance over the sphere.

        The path tracer combines these samples with the BTF's own by MIS, and the BTF's
        sampling covers every direction above the surface, so leaving the smooth part of the
        sky to it stays unbiased; the environment's samples then go where the BTF's cannot
        find the light (a sun, a window). Time to the same error: docs/accuracy.md, "MIS
        compensation". A map with nothing above its mean (a constant colour) keeps the plain
        tables. float32, as the kernels read them; built on first use (the viewport's virtual
        lights never need them)."""
        excess = self._excess()
        # black, or nothing above the mean: the plain tables
        return _float32(self.tables if excess is None else sampling_tables(excess))

    @functools.cached_property
    def sun_tables(self) -> tuple[SamplingTables, SunTable | None]:
        """The final render's next-event draws where the map has a sun: the MIS-compensated
        tables without the sun's pixels, and the sun's own (both ∝ the compensated weight:
        drawn one or the other by the sun's share, they are mis_tables). At a glossy camera
        vertex the kernel draws from both, and MIS weighs the two and the BTF's sampling
        (kernels/render_direct.cl). Without a sun: ``(mis_tables, None)``.

        The sun: the pixels at least SUN_RATIO times the mean luminance, when they hold at
        least SUN_MIN_SHARE of the light above the mean in at most SUN_MAX_PIXELS of the map.
        Drawn from the whole table, such a source is found by few draws (forest.exr's 1793
        pixels above 16 × its mean hold 34 % of the compensated weight, city.exr's 83 hold
        42 %), and each find is a rare bright sample on a glossy lobe; drawn on its own every
        time, it is a smooth term. Time to the same error: docs/accuracy.md, "The sun's own
        draws"."""
        excess = self._excess()
        if excess is None:
            return self.mis_tables, None
        # L ≥ SUN_RATIO · L̄ ⟺ (L − L̄) · sin θ ≥ (SUN_RATIO − 1) · L̄ · sin θ: from the excess,
        # not a luminance map of its own (a float32 map's would cost F12 milliseconds)
        sun = excess >= (SUN_RATIO - 1.0) * self.mean_luminance * self._sin_rows[:, None]
        count = int(np.count_nonzero(sun))
        total = excess.sum()
        inside = excess[sun].sum()
        # The rest summed on its own: total − inside is rounding where the sun holds all of
        # the light above the mean (a dim sky with one small lamp), and tables of a rest that
        # is 0 are NaN.
        rest = float(np.sum(excess, where=~sun))
        if (
            count == 0
            or count > SUN_MAX_PIXELS * sun.size
            or inside < SUN_MIN_SHARE * total
            or not rest > 0.0  # the sun is all there is: the compensated tables are it
        ):
            return _float32(sampling_tables(excess)), None  # mis_tables, from this excess
        # the lobe window's rule, before the sun leaves the excess
        bright = excess >= (WINDOW_RATIO - 1.0) * self.mean_luminance * self._sin_rows[:, None]
        self._patchy_share = float((excess[bright].sum() - inside) / rest)
        pixels = np.flatnonzero(sun)
        weight = excess.ravel()[pixels]  # the compensated weights, within the sun
        cdf = np.concatenate([[0.0], np.cumsum(weight)])
        cdf /= cdf[-1]
        probability = (weight / weight.sum()).astype(np.float32)
        share = float(inside / total)
        table = SunTable(pixels.astype(np.int32), cdf.astype(np.float32), probability, share)
        excess[sun] = 0.0
        return _float32(sampling_tables(excess)), table

    @functools.cached_property
    def lobe_window(self) -> LobeWindowTable | None:
        """The block sums of the tables drawn beside the sun (``sun_tables``), for the lobe
        window drawn at a glossy camera vertex (kernels/include/btf_env_window.h). None (no
        window) for a map without a sun, one whose light beside the sun is not patchy (see
        WINDOW_MIN_SHARE: where it is smooth the lobe's own draws find it, and the window
        cost city.exr's GGX sphere 18–31 % more per sample for nothing) or one too tall for the
        kernel's block. Cached with the Environment: F12 after F12 of one World builds it
        once."""
        tables, sun = self.sun_tables
        too_tall = self.height > WINDOW_BLOCK_ROWS * WINDOW_MAX_BLOCK
        if sun is None or too_tall or self._patchy_share < WINDOW_MIN_SHARE:
            return None
        return lobe_window_table(tables)

    # --- kept on disk between sessions ------------------------------------------------------
    def state(self) -> dict[str, np.ndarray]:
        """The map as the final render's Sampled mode uses it, as arrays: the cleaned and scaled
        radiance (a float32 map's as the RGBA texture, ``rgba32``, which F12 uploads: that
        texture is then not built again), the numbers measured from it, the sun's tables and
        the lobe window (built now where they are not yet). ``from_state`` makes the same
        Environment from them without computing anything of the map
        (blender/export/world_cache.py keeps them on disk: on forest.exr they were ~25 ms of a
        fresh Blender's F12)."""
        tables, sun = self.sun_tables
        window = self.lobe_window
        measured = (self.mean_luminance, self.is_black, self._patchy_share)
        counts = (self.nonfinite_count, self.negative_count)
        out = {"scalars": np.array([*measured, *counts], np.float64)}
        if self.radiance.dtype == np.float32:
            out["rgba"] = self.rgba32()
        else:  # float64 (a map made in numpy): kept as it is, not rounded to the texture's
            out["radiance"] = self.radiance
        out.update({f"tables_{name}": table for name, table in tables._asdict().items()})
        if sun is not None:
            out.update(sun_pixels=sun.pixels, sun_cdf=sun.cdf, sun_probability=sun.probability)
            out["sun_share"] = np.array(sun.share, np.float64)
        if window is not None:
            out.update(window_row_pdf=window.row_pdf, window_cdf=window.cdf)
            out["window_block"] = np.array(window.block, np.int64)
        return out

    @classmethod
    def from_state(cls, state: dict[str, np.ndarray], rotation_z_rad: float = 0.0) -> Environment:
        """The Environment whose ``state()`` this is (checked by ``valid_state`` first), turned
        by ``rotation_z_rad`` (the tables are in the image's own coordinates)."""
        env = cls.__new__(cls)
        env._rgba = state.get("rgba")
        env.radiance = env._rgba[..., :3] if env._rgba is not None else state["radiance"]
        env.height, env.width = env.radiance.shape[:2]
        env.rotation_z_rad = float(rotation_z_rad)
        mean, black, patchy, nonfinite, negative = (float(x) for x in state["scalars"])
        env.mean_luminance, env.is_black, env._patchy_share = mean, bool(black), patchy
        env.nonfinite_count, env.negative_count = int(nonfinite), int(negative)
        env._sin_rows = np.sin(np.pi * (np.arange(env.height) + 0.5) / env.height)
        env._tables_lock = threading.Lock()
        env._weight = None  # the plain tables, where asked for, from the radiance (``tables``)
        tables = SamplingTables(*(state[f"tables_{name}"] for name in SamplingTables._fields))
        sun = None
        if "sun_pixels" in state:
            parts = (state["sun_pixels"], state["sun_cdf"], state["sun_probability"])
            sun = SunTable(*parts, float(state["sun_share"]))
        else:
            env.__dict__["mis_tables"] = tables  # what sun_tables holds without a sun
        env.__dict__["sun_tables"] = (tables, sun)
        window = None
        if "window_block" in state:
            block = int(state["window_block"])
            window = LobeWindowTable(block, state["window_row_pdf"], state["window_cdf"])
        env.__dict__["lobe_window"] = window
        return env

    @staticmethod
    def valid_state(state: dict[str, np.ndarray]) -> bool:
        """Whether arrays read back are a ``state()`` this code made: every array there with its
        dtype and a shape that fits the radiance's, the numbers finite (a damaged or foreign
        file is then built again, never used)."""
        kept = "rgba" if "rgba" in state else "radiance"
        radiance = state.get(kept)
        if radiance is None or radiance.ndim != 3 or radiance.shape[2] != 4 - (kept != "rgba"):
            return False
        h, w = radiance.shape[:2]
        f32, i32 = np.dtype(np.float32), np.dtype(np.int32)
        pixels = (f32, (h, w, 4)) if kept == "rgba" else (np.dtype(np.float64), (h, w, 3))
        expected = {
            kept: pixels,
            "scalars": (np.dtype(np.float64), (5,)),
            "tables_row_pdf": (f32, (h,)),
            "tables_row_cdf": (f32, (h + 1,)),
            "tables_col_pdf": (f32, (h, w)),
            "tables_col_cdf": (f32, (h, w + 1)),
        }
        if "sun_pixels" in state:
            k = state["sun_pixels"].shape[0] if state["sun_pixels"].ndim == 1 else -1
            expected.update(sun_pixels=(i32, (k,)), sun_cdf=(f32, (k + 1,)))
            expected.update(sun_probability=(f32, (k,)), sun_share=(np.dtype(np.float64), ()))
        if "window_block" in state:  # lobe_window_table's layout for this map
            block = -(-h // WINDOW_BLOCK_ROWS)
            rows, cols = -(-h // block), -(-w // block)
            expected.update(window_block=(np.dtype(np.int64), ()), window_row_pdf=(f32, (rows,)))
            expected["window_cdf"] = (f32, (rows, cols + 1))
        if set(state) != set(expected):
            return False
        for name, (dtype, shape) in expected.items():
            array = state[name]
            if array.dtype != dtype or array.shape != shape or not np.isfinite(array).all():
                return False
        if "window_block" in state and int(state["window_block"]) != block:
            return False
        # the kernels index the map by these: one outside it would read beyond the buffer
        sun_pixels = state.get("sun_pixels", np.zeros(0, np.int32))
        return not sun_pixels.size or (sun_pixels.min() >= 0 and sun_pixels.max() < h * w)

    # --- mapping ---------------------------------------------------------------------------
    def _rot(self, angle: float) -> np.ndarray:
        c, s = np.cos(angle), np.sin(angle)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def image_coords(self, world_dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) world directions → (s, t) in [0, 1): s across, t down from the top row."""
        d = np.asarray(world_dirs, dtype=np.float64) @ self._rot(self.rotation_z_rad).T
        d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
        s = np.mod((np.pi - np.arctan2(d[:, 1], d[:, 0])) / (2 * np.pi), 1.0)
        t = np.arccos(np.clip(d[:, 2], -1.0, 1.0)) / np.pi
        return s, np.minimum(t, np.nextafter(1.0, 0.0))

    def directions_from_image_coords(self, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        theta = np.pi * t
        phi = np.pi - 2 * np.pi * s
        m = np.column_stack(
            [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]
        )
        return m @ self._rot(-self.rotation_z_rad).T

    def _pixel(self, s: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        col = np.minimum((s * self.width).astype(np.int64), self.width - 1)
        row = np.minimum((t * self.height).astype(np.int64), self.height - 1)
        return row, col

    def lookup(self, world_dirs: np.ndarray) -> np.ndarray:
        """Radiance (N, 3) seen in each direction (nearest pixel, as Closest interpolation)."""
        row, col = self._pixel(*self.image_coords(world_dirs))
        return self.radiance[row, col]

    # --- sampling --------------------------------------------------------------------------
    def pdf(self, world_dirs: np.ndarray, tables: SamplingTables | None = None) -> np.ndarray:
        """Solid-angle density (N,) of ``sample`` producing each direction (of a draw from
        ``tables`` when given: ``mis_tables``)."""
        row_pdf, _, col_pdf, _ = self.tables if tables is None else tables
        s, t = self.image_coords(world_dirs)
        row, col = self._pixel(s, t)
        pdf_image = row_pdf[row] * col_pdf[row, col].astype(np.float64) * self.width * self.height
        sin_t = np.maximum(np.sin(np.pi * t), MIN_SIN_THETA)
        return pdf_image / (2 * np.pi * np.pi * sin_t)

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, 2) uniform numbers → direction (N, 3), radiance (N, 3), pdf (N,)."""
        u = np.clip(np.asarray(u, dtype=np.float64), 0.0, np.nextafter(1.0, 0.0))
        row = np.clip(np.searchsorted(self.row_cdf, u[:, 0], side="right") - 1, 0, self.height - 1)
        row_lo = self.row_cdf[row]
        row_w = np.maximum(self.row_cdf[row + 1] - row_lo, 1e-300)
        dt = np.clip((u[:, 0] - row_lo) / row_w, 0.0, np.nextafter(1.0, 0.0))
        col = np.clip(self._search_columns(row, u[:, 1]), 0, self.width - 1)
        col_lo = self.col_cdf[row, col]
        col_w = np.maximum(self.col_cdf[row, col + 1] - col_lo, 1e-300)
        ds = np.clip((u[:, 1] - col_lo) / col_w, 0.0, np.nextafter(1.0, 0.0))
        s = (col + ds) / self.width
        t = (row + dt) / self.height
        pdf_image = self.row_pdf[row] * self.col_pdf[row, col] * self.width * self.height
        sin_t = np.maximum(np.sin(np.pi * t), MIN_SIN_THETA)
        return (
            self.directions_from_image_coords(s, t),
            self.radiance[row, col],
            pdf_image / (2 * np.pi * np.pi * sin_t),
        )

    def _search_columns(self, row: np.ndarray, u1: np.ndarray) -> np.ndarray:
        """(N,) rows and numbers → (N,) index of the last column cdf entry ≤ u1 (−1 if none).

        One binary search per distinct row over that row's cdf: memory O(N), never the
        (N × width) comparison matrix (10⁶ lights over an 8k-wide map would need 8 GB). Each
        cdf row is non-decreasing, so the count of entries ≤ u1 is searchsorted's 'right'."""
        col = np.empty(len(row), dtype=np.int64)
        order = np.argsort(row, kind="stable")
        rows_sorted = row[order]
        starts = np.flatnonzero(np.r_[True, rows_sorted[1:] != rows_sorted[:-1]])
        ends = np.r_[starts[1:], len(order)]
        for start, end in zip(starts, ends, strict=True):
            idx = order[start:end]
            col[idx] = np.searchsorted(self.col_cdf[rows_sorted[start]], u1[idx], side="right")
        return col - 1

    def invert(self, world_dirs: np.ndarray) -> np.ndarray:
        """The (N, 2) uniform numbers that ``sample`` maps to these directions."""
        s, t = self.image_coords(world_dirs)
        row, col = self._pixel(s, t)
        u0 = self.row_cdf[row] + (t * self.height - row) * self.row_pdf[row]
        u1 = self.col_cdf[row, col] + (s * self.width - col) * self.col_pdf[row, col]
        return np.column_stack([u0, u1])

    def virtual_lights(self, n: int = 256, seed: int = 0) -> VirtualLights:
        """N lights from a digitally shifted Sobol sequence: each prefix is stratified."""
        if n < 1:
            raise ValueError("need at least one virtual light")
        direction, radiance, pdf = self.sample(sobol_2d(n, seed))
        return VirtualLights(direction, radiance, pdf)

    # --- reference integration -------------------------------------------------------------
    def irradiance_reference(self, normals: np.ndarray, supersample: int = 4) -> np.ndarray:
        """(M, 3) normals → (M, 3) irradiance by quadrature over every pixel.

        Each pixel is split into sub-cells (at least 256 × 128 over the sphere, so tiny maps are
        integrated as finely as large ones); a sub-cell's solid angle is exact
        (Δφ·(cos θ0 − cos θ1)) and its cosine is taken at its centre.
        """
        h, w = self.height, self.width
        kr = max(supersample, -(-128 // h))
        kc = max(supersample, -(-256 // w))
        rows, cols = h * kr, w * kc
        edges = np.pi * np.arange(rows + 1) / rows
        band = (2 * np.pi / cols) * (np.cos(edges[:-1]) - np.cos(edges[1:]))
        s = (np.arange(cols) + 0.5) / cols
        normals = np.asarray(normals, dtype=np.float64)
        out = np.zeros((len(normals), 3))
        rad_cols = np.repeat(self.radiance, kc, axis=1)  # (h, cols, 3)
        for r in range(rows):  # one sub-row at a time bounds memory for big maps
            dirs = self.directions_from_image_coords(s, np.full(cols, (r + 0.5) / rows))
            cos = np.maximum(normals @ dirs.T, 0.0) * band[r]
            out += cos @ rad_cols[r // kr]
        return out

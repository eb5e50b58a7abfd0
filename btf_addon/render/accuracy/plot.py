"""A small line-plot raster in numpy: axes with linear or log scales, tick labels, axis labels,
a title, a legend, lines with markers, reference lines. Text is the HUD's bitmap font
(render/hud.py ``raster_text``); files are written by core/formats/imageio.py's PNG writer.

Why not matplotlib: the plots are needed inside Blender (the render-settings panel shows the
curve), where matplotlib is not available and bundling it (with its C extensions, per platform
and Python version) would multiply the extension's size for a few line charts. The same raster
serves the panel, the CLI report and docs/accuracy.md, so they cannot disagree.

Images are (h, w, 3) uint8 with row 0 at the TOP (as files store them).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..hud import CELL_H, CELL_W, raster_text

WHITE = (255, 255, 255)
BLACK = (0, 0, 0)
GREY = (200, 200, 200)

#: Distinguishable line colours (Okabe & Ito's colour-blind-safe palette), cycled.
PALETTE = (
    (0, 114, 178),
    (213, 94, 0),
    (0, 158, 115),
    (204, 121, 167),
    (230, 159, 0),
    (86, 180, 233),
    (120, 120, 120),
)


@dataclass
class Series:
    label: str
    x: Sequence[float]
    y: Sequence[float]
    colour: tuple[int, int, int] | None = None  # None: the palette's next
    width: int = 2  # line thickness in pixels (0: markers only)
    marker: int = 3  # half-size of the square marker (0: none)


@dataclass
class Plot:
    series: list[Series] = field(default_factory=list)
    title: str = ""
    x_label: str = ""
    y_label: str = ""
    x_log: bool = False
    y_log: bool = False
    hlines: list[tuple[float, str]] = field(default_factory=list)  # (y, label), dashed
    vlines: list[tuple[float, str]] = field(default_factory=list)  # (x, label), dashed
    rings: list[tuple[float, float]] = field(default_factory=list)  # circled points


def render_plot(plot: Plot, width: int = 640, height: int = 400, scale: int = 1) -> np.ndarray:
    """The plot as an (height, width, 3) uint8 image, row 0 at the top. ``scale`` multiplies
    the font (1 = 5 × 7 pixel glyphs). Non-finite and, on log axes, non-positive values are
    left out; an axis with nothing to show spans [1, 10] (log) or [0, 1]."""
    if width < 120 or height < 80:
        raise ValueError(f"a plot needs at least 120 × 80 pixels, got {width} × {height}")
    img = np.full((height, width, 3), 255, np.uint8)
    char_w, char_h = CELL_W * scale, CELL_H * scale
    xs = [v for s in plot.series for v in s.x] + [v for v, _ in plot.vlines]
    ys = [v for s in plot.series for v in s.y] + [v for v, _ in plot.hlines]
    x_axis = _Axis(xs, plot.x_log)
    y_axis = _Axis(ys, plot.y_log)
    y_tick_text = [_fmt(v) for v in y_axis.ticks]
    left = 8 + char_w * (max((len(t) for t in y_tick_text), default=1) + 1) + char_h
    right = width - 12
    top = 8 + (char_h + 6 if plot.title else 0)
    bottom = height - (8 + 2 * char_h + 8)
    if right - left < 40 or bottom - top < 30:
        raise ValueError("the plot is too small for its labels")

    def px(v):
        return left + x_axis.frac(v) * (right - left)

    def py(v):
        return bottom - y_axis.frac(v) * (bottom - top)

    for v in x_axis.ticks:  # grid, then frame, ticks and labels
        _line(img, px(v), top, px(v), bottom, GREY, 1)
    for v in y_axis.ticks:
        _line(img, left, py(v), right, py(v), GREY, 1)
    _rect(img, left, top, right, bottom, BLACK)
    for v in x_axis.ticks:
        text = _fmt(v)
        _text(img, text, px(v) - len(text) * char_w / 2, bottom + 4, scale, BLACK)
    for v, text in zip(y_axis.ticks, y_tick_text, strict=True):
        _text(img, text, left - 4 - len(text) * char_w, py(v) - char_h / 2, scale, BLACK)
    if plot.title:
        _text(img, plot.title, (width - len(plot.title) * char_w) / 2, 6, scale, BLACK)
    if plot.x_label:
        x0 = (left + right - len(plot.x_label) * char_w) / 2
        _text(img, plot.x_label, x0, bottom + 6 + char_h, scale, BLACK)
    if plot.y_label:  # vertical: the text raster rotated a quarter turn
        label = _text_raster(plot.y_label, scale, BLACK)
        label = np.rot90(label)
        y0 = int((top + bottom - label.shape[0]) / 2)
        _blit(img, label, 4, max(y0, 0))

    for v, text in plot.hlines:
        if y_axis.shows(v):
            _dashed(img, left, py(v), right, py(v), BLACK)
            _text(img, text, left + 4, py(v) - char_h - 1, scale, BLACK)  # clear of the legend
    for v, text in plot.vlines:
        if x_axis.shows(v):
            _dashed(img, px(v), top, px(v), bottom, BLACK)
            _text(img, text, px(v) + 3, bottom - char_h - 2, scale, BLACK)

    colours = _colours(plot.series)
    clip = (left, top, right, bottom)
    for s, colour in zip(plot.series, colours, strict=True):
        pts = [
            (px(a), py(b))
            for a, b in zip(s.x, s.y, strict=True)
            if x_axis.shows(a) and y_axis.shows(b)
        ]
        if s.width:
            for (x0, y0), (x1, y1) in itertools.pairwise(pts):
                _line(img, x0, y0, x1, y1, colour, s.width, clip)
        for x0, y0 in pts if s.marker else ():
            _square(img, x0, y0, s.marker, colour, clip)
    for a, b in plot.rings:
        if x_axis.shows(a) and y_axis.shows(b):
            _ring(img, px(a), py(b), 8, BLACK)

    labelled = [(s, c) for s, c in zip(plot.series, colours, strict=True) if s.label]
    if labelled:  # legend: top right inside the frame, on white
        longest = max(len(s.label) for s, _ in labelled)
        box_w, box_h = 26 + longest * char_w, 6 + len(labelled) * (char_h + 3)
        x0, y0 = right - box_w - 6, top + 6
        img[y0 : y0 + box_h, x0 : x0 + box_w] = 255
        _rect(img, x0, y0, x0 + box_w, y0 + box_h, GREY)
        for n, (s, colour) in enumerate(labelled):
            yy = y0 + 4 + n * (char_h + 3)
            _line(img, x0 + 4, yy + char_h / 2, x0 + 18, yy + char_h / 2, colour, max(s.width, 1))
            if s.marker:
                _square(img, x0 + 11, yy + char_h / 2, min(s.marker, 3), colour)
            _text(img, s.label, x0 + 22, yy, scale, BLACK)
    return img


class _Axis:
    def __init__(self, values: Sequence[float], log: bool):
        self.log = log
        v = [float(a) for a in values if math.isfinite(a) and (a > 0 or not log)]
        if log:
            lo, hi = (min(v), max(v)) if v else (1.0, 10.0)
            self.lo, self.hi = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
            if self.hi == self.lo:
                self.hi += 1
            decades = range(self.lo, self.hi + 1)
            steps = (1,) if len(decades) > 3 else (1, 2, 5)
            self.ticks = [m * 10.0**d for d in decades for m in steps if m * 10.0**d <= 10**self.hi]
        else:
            lo, hi = (min(v), max(v)) if v else (0.0, 1.0)
            lo = min(lo, 0.0) if lo >= 0 else lo
            hi = hi if hi > lo else lo + 1.0
            step = _nice_step((hi - lo) / 5)
            self.lo, self.hi = math.floor(lo / step) * step, math.ceil(hi / step) * step
            count = round((self.hi - self.lo) / step)
            self.ticks = [self.lo + i * step for i in range(count + 1)]

    def frac(self, v: float) -> float:
        if self.log:
            return (math.log10(v) - self.lo) / (self.hi - self.lo)
        return (v - self.lo) / (self.hi - self.lo)

    def shows(self, v: float) -> bool:
        return math.isfinite(v) and (v > 0 or not self.log) and -1e-9 <= self.frac(v) <= 1 + 1e-9


def _nice_step(raw: float) -> float:
    exp = math.floor(math.log10(raw))
    for m in (1, 2, 5, 10):
        if m * 10.0**exp >= raw:
            return m * 10.0**exp
    return 10.0 ** (exp + 1)


def _fmt(v: float) -> str:
    if v == 0:
        return "0"
    if abs(v) >= 1e4 or abs(v) < 1e-3:
        return f"{v:.0e}".replace("e-0", "e-").replace("e+0", "e")
    return f"{v:g}"


def _colours(series: Sequence[Series]) -> list[tuple[int, int, int]]:
    out, n = [], 0
    for s in series:
        if s.colour is None:
            out.append(PALETTE[n % len(PALETTE)])
            n += 1
        else:
            out.append(s.colour)
    return out


def _text_raster(text: str, scale: int, colour) -> np.ndarray:
    """(h, w, 4) uint8 RGBA, row 0 at the top, transparent background."""
    rgba = raster_text(
        [text],
        scale=scale,
        foreground=(*np.divide(colour, 255), 1.0),
        background=(0.0, 0.0, 0.0, 0.0),
        padding=0,
    )[::-1]
    alpha = rgba[..., 3:]
    rgb = np.where(alpha > 0, rgba[..., :3] / np.maximum(alpha, 1e-6), 0.0)
    return np.concatenate([rgb * 255, alpha * 255], axis=-1).round().astype(np.uint8)


def _blit(img: np.ndarray, rgba: np.ndarray, x: float, y: float) -> None:
    x, y = round(x), round(y)
    h, w = rgba.shape[:2]
    y0, x0 = max(y, 0), max(x, 0)
    y1, x1 = min(y + h, img.shape[0]), min(x + w, img.shape[1])
    if y1 <= y0 or x1 <= x0:
        return
    src = rgba[y0 - y : y1 - y, x0 - x : x1 - x]
    a = src[..., 3:].astype(np.float32) / 255
    dst = img[y0:y1, x0:x1].astype(np.float32)
    img[y0:y1, x0:x1] = (src[..., :3] * a + dst * (1 - a)).round().astype(np.uint8)


def _text(img, text: str, x: float, y: float, scale: int, colour) -> None:
    _blit(img, _text_raster(text, scale, colour), x, y)


def _stamp(img, xs, ys, colour, width: int, clip=None) -> None:
    xs, ys = np.round(xs).astype(int), np.round(ys).astype(int)
    lo, hi = -(width // 2), width - width // 2
    x_min, y_min, x_max, y_max = clip or (0, 0, img.shape[1] - 1, img.shape[0] - 1)
    for dy in range(lo, hi):
        for dx in range(lo, hi):
            cx, cy = xs + dx, ys + dy
            ok = (cx >= x_min) & (cx <= x_max) & (cy >= y_min) & (cy <= y_max)
            ok &= (cx >= 0) & (cx < img.shape[1]) & (cy >= 0) & (cy < img.shape[0])
            img[cy[ok], cx[ok]] = colour


def _line(img, x0, y0, x1, y1, colour, width: int = 1, clip=None) -> None:
    n = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
    t = np.linspace(0.0, 1.0, n + 1)
    _stamp(img, x0 + t * (x1 - x0), y0 + t * (y1 - y0), colour, width, clip)


def _dashed(img, x0, y0, x1, y1, colour, dash: int = 6) -> None:
    n = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
    t = np.linspace(0.0, 1.0, n + 1)
    keep = (np.arange(n + 1) // dash) % 2 == 0
    _stamp(img, (x0 + t * (x1 - x0))[keep], (y0 + t * (y1 - y0))[keep], colour, 1)


def _rect(img, x0, y0, x1, y1, colour) -> None:
    for a, b, c, d in ((x0, y0, x1, y0), (x0, y1, x1, y1), (x0, y0, x0, y1), (x1, y0, x1, y1)):
        _line(img, a, b, c, d, colour, 1)


def _square(img, x, y, half: int, colour, clip=None) -> None:
    _stamp(img, np.array([x]), np.array([y]), colour, 2 * half + 1, clip)


def _ring(img, x, y, radius: float, colour) -> None:
    t = np.linspace(0, 2 * np.pi, int(8 * radius) + 8)
    _stamp(img, x + radius * np.cos(t), y + radius * np.sin(t), colour, 2)


# ---------------------------------------------------------------------------------------------
# Heat maps

#: Colour map stops (value, RGB): black → purple → red → yellow → white, monotone in
#: lightness, so the map reads in greyscale too (an "inferno"-like ramp, our own stops).
HEAT_STOPS = (
    (0.0, (0, 0, 4)),
    (0.25, (87, 16, 110)),
    (0.5, (188, 55, 84)),
    (0.75, (249, 142, 9)),
    (1.0, (252, 255, 164)),
)


def heat_colours(values: np.ndarray, vmax: float) -> np.ndarray:
    """(h, w) values ≥ 0 → (h, w, 3) uint8 through HEAT_STOPS, 0 … vmax (clipped)."""
    t = np.clip(np.nan_to_num(np.asarray(values, np.float64)) / max(vmax, 1e-30), 0.0, 1.0)
    stops = np.array([s for s, _ in HEAT_STOPS])
    rgb = np.array([c for _, c in HEAT_STOPS], np.float64)
    out = np.stack([np.interp(t, stops, rgb[:, k]) for k in range(3)], axis=-1)
    return out.round().astype(np.uint8)


def heat_map(values: np.ndarray, vmax: float, label: str, min_width: int = 320) -> np.ndarray:
    """A heat map image with its colour bar and ``label`` below: the (h, w) map enlarged by a
    whole factor (nearest) to at least ``min_width`` pixels wide; (H, W, 3) uint8."""
    _h, w = values.shape
    k = max(1, math.ceil(min_width / w))
    body = np.repeat(np.repeat(heat_colours(values, vmax), k, axis=0), k, axis=1)
    width = body.shape[1]
    bar = np.repeat(heat_colours(np.linspace(0, vmax, width)[None, :], vmax), 10, axis=0)
    caption_h = CELL_H + 8
    canvas = np.full((body.shape[0] + 4 + bar.shape[0] + caption_h, width, 3), 255, np.uint8)
    canvas[: body.shape[0]] = body
    canvas[body.shape[0] + 4 : body.shape[0] + 4 + bar.shape[0]] = bar
    y = body.shape[0] + 4 + bar.shape[0] + 3
    right = f"{_fmt(vmax)}+"
    _text(canvas, "0", 2, y, 1, BLACK)
    _text(canvas, right, width - len(right) * CELL_W - 2, y, 1, BLACK)
    text = label[: max((width - 2 * CELL_W * 8) // CELL_W, 0)]
    _text(canvas, text, (width - len(text) * CELL_W) / 2, y, 1, BLACK)
    return canvas

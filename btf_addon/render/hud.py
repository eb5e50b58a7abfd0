"""The VR HUD, bpy-free: its text, a bitmap-font raster of that text, and the quad it is shown
on, fixed to the head in view space (gl/hud.py draws it per eye).

A 2D overlay is unreadable in a headset (the thesis found so): the HUD is a textured quad at
a fixed distance in front of the viewer, drawn into each eye with that eye's own matrices, so
it has the stereo disparity of a real object at that distance.

The font is this module's own 5 × 7 ASCII font (plus one descender row), printable ASCII
32–126, one glyph as 8 row bytes (top row first, bit 4 = leftmost column), written for this
project (no third-party glyph data). Each glyph sits in a 6 × 9 cell (one column and one row of
spacing).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

MAX_LINES = 40  # a HUD page, not a document: bounds the texture (and its upload) per frame
MAX_CHARS = 120  # per line
GLYPH_W, GLYPH_H = 5, 8  # font pixels: 7 rows above the baseline + 1 descender row
CELL_W, CELL_H = GLYPH_W + 1, GLYPH_H + 1  # advance between characters / lines

# Characters the HUD's own text uses that the font lacks, as ASCII stand-ins.
STAND_INS = {"·": ".", "×": "x", "−": "-", "–": "-", "—": "-", "…": "..."}

# fmt: off
_FONT_HEX = (
    "0000000000000000",  # ' '
    "0404040404000400",  # '!'
    "0a0a0a0000000000",  # '"'
    "0a0a1f0a1f0a0a00",  # '#'
    "040f140e051e0400",  # '$'
    "1819020408130300",  # '%'
    "0c12140815120d00",  # '&'
    "0404080000000000",  # "'"
    "0204080808040200",  # '('
    "0804020202040800",  # ')'
    "0004150e15040000",  # '*'
    "0004041f04040000",  # '+'
    "00000000000c0408",  # ','
    "0000001f00000000",  # '-'
    "00000000000c0c00",  # '.'
    "0001020408100000",  # '/'
    "0e11131519110e00",  # '0'
    "040c040404040e00",  # '1'
    "0e11010204081f00",  # '2'
    "1f02040201110e00",  # '3'
    "02060a121f020200",  # '4'
    "1f101e0101110e00",  # '5'
    "0608101e11110e00",  # '6'
    "1f01020408080800",  # '7'
    "0e11110e11110e00",  # '8'
    "0e11110f01020c00",  # '9'
    "000c0c000c0c0000",  # ':'
    "000c0c000c040800",  # ';'
    "0204081008040200",  # '<'
    "00001f001f000000",  # '='
    "0804020102040800",  # '>'
    "0e11010204000400",  # '?'
    "0e11010d15150e00",  # '@'
    "0e11111f11111100",  # 'A'
    "1e11111e11111e00",  # 'B'
    "0e11101010110e00",  # 'C'
    "1c12111111121c00",  # 'D'
    "1f10101e10101f00",  # 'E'
    "1f10101e10101000",  # 'F'
    "0e11101711110f00",  # 'G'
    "1111111f11111100",  # 'H'
    "0e04040404040e00",  # 'I'
    "0702020202120c00",  # 'J'
    "1112141814121100",  # 'K'
    "1010101010101f00",  # 'L'
    "111b151511111100",  # 'M'
    "1111191513111100",  # 'N'
    "0e11111111110e00",  # 'O'
    "1e11111e10101000",  # 'P'
    "0e11111115120d00",  # 'Q'
    "1e11111e14121100",  # 'R'
    "0f10100e01011e00",  # 'S'
    "1f04040404040400",  # 'T'
    "1111111111110e00",  # 'U'
    "11111111110a0400",  # 'V'
    "1111111515150a00",  # 'W'
    "11110a040a111100",  # 'X'
    "11110a0404040400",  # 'Y'
    "1f01020408101f00",  # 'Z'
    "0e08080808080e00",  # '['
    "0010080402010000",  # '\\'
    "0e02020202020e00",  # ']'
    "040a110000000000",  # '^'
    "000000000000001f",  # '_'
    "0804020000000000",  # '`'
    "00000e010f110f00",  # 'a'
    "1010161911111e00",  # 'b'
    "00000e1010110e00",  # 'c'
    "01010d1311110f00",  # 'd'
    "00000e111f100e00",  # 'e'
    "0609081c08080800",  # 'f'
    "00000f11110f010e",  # 'g'
    "1010161911111100",  # 'h'
    "04000c0404040e00",  # 'i'
    "020006020202120c",  # 'j'
    "1010121418141200",  # 'k'
    "0c04040404040e00",  # 'l'
    "00001a1515111100",  # 'm'
    "0000161911111100",  # 'n'
    "00000e1111110e00",  # 'o'
    "00001e11111e1010",  # 'p'
    "00000f11110f0101",  # 'q'
    "0000161910101000",  # 'r'
    "00000f100e011e00",  # 's'
    "08081c0808090600",  # 't'
    "0000111111130d00",  # 'u'
    "00001111110a0400",  # 'v'
    "0000111115150a00",  # 'w'
    "0000110a040a1100",  # 'x'
    "00001111110f010e",  # 'y'
    "00001f0204081f00",  # 'z'
    "0204040804040200",  # '{'
    "0404040404040400",  # '|'
    "0804040204040800",  # '}'
    "0000081502000000",  # '~'
)
# fmt: on
_FIRST = 32
_QUESTION = ord("?") - _FIRST


def _font_bitmaps() -> np.ndarray:
    """(95, 8, 5) bool: glyph rows top to bottom, columns left to right."""
    data = bytes.fromhex("".join(_FONT_HEX))
    rows = np.frombuffer(data, dtype=np.uint8).reshape(-1, GLYPH_H, 1)
    bits = 1 << np.arange(GLYPH_W - 1, -1, -1, dtype=np.uint8)  # bit 4 = leftmost column
    return (rows & bits) != 0


_GLYPHS = _font_bitmaps()


def status_lines(
    material: str, lights_done: int, lights_total: int, budget_status: str
) -> list[str]:
    """The HUD's status text, top line first: the material's name, lights accumulated so far
    (e.g. ``lights 45/200``), the frame-budget status (render/frame_budget.py's words). Lines
    longer than ``MAX_CHARS`` are shortened with ``...`` so ``raster_text`` always accepts them."""
    lines = [material or "(no BTF material)", f"lights {lights_done}/{lights_total}"]
    if budget_status:
        lines.append(budget_status)
    return [_shorten(_ascii(line)) for line in lines]


def _ascii(text: str) -> str:
    for char, stand_in in STAND_INS.items():
        text = text.replace(char, stand_in)
    return text


def _shorten(line: str) -> str:
    return line if len(line) <= MAX_CHARS else line[: MAX_CHARS - 3] + "..."


def _premultiplied(colour: Sequence[float], name: str) -> np.ndarray:
    rgba = np.asarray(colour, dtype=np.float64)
    if rgba.shape != (4,) or not np.all((rgba >= 0.0) & (rgba <= 1.0)):
        raise ValueError(f"{name} must be 4 values (r, g, b, a) in [0, 1], got {colour!r}")
    return np.concatenate([rgba[:3] * rgba[3], rgba[3:]])


def raster_text(
    lines: Sequence[str],
    scale: int = 2,
    foreground: Sequence[float] = (1.0, 1.0, 1.0, 1.0),
    background: Sequence[float] = (0.0, 0.0, 0.0, 0.6),
    padding: int = 4,
) -> np.ndarray:
    """``lines`` (top line first) drawn in the bitmap font → ``(h, w, 4)`` float32, PREMULTIPLIED
    alpha, row 0 = the BOTTOM row (OpenGL's upload order: drawn on a quad whose t = 0 is at the
    bottom, the text reads upright).

    Each font pixel is ``scale`` × ``scale`` image pixels; ``padding`` image pixels of
    background surround the text. ``foreground``/``background`` are straight (not
    premultiplied) RGBA in [0, 1]; a glyph pixel is the foreground "over" the background.
    Size: w = 2·padding + scale·(6·longest − 1), h = 2·padding + scale·(9·len(lines) − 1)
    (at least one character and one line, so the image is never empty). Characters outside
    printable ASCII are drawn as ``?``, after the ``STAND_INS`` replacements.
    Raises ValueError for more than ``MAX_LINES`` lines or ``MAX_CHARS`` characters in a line
    (after replacements), a scale below 1, a negative padding or colours out of range."""
    if isinstance(lines, str):
        raise TypeError("lines must be a list of strings, not one string")
    if not isinstance(scale, int | np.integer) or scale < 1:
        raise ValueError(f"scale must be an integer >= 1, got {scale!r}")
    if not isinstance(padding, int | np.integer) or padding < 0:
        raise ValueError(f"padding must be an integer >= 0, got {padding!r}")
    text = [_ascii(str(line)) for line in lines] or [""]
    if len(text) > MAX_LINES:
        raise ValueError(f"{len(text)} lines: the HUD shows at most {MAX_LINES}")
    longest = max(len(line) for line in text)
    if longest > MAX_CHARS:
        raise ValueError(f"a line of {longest} characters: the HUD shows at most {MAX_CHARS}")
    fg, bg = _premultiplied(foreground, "foreground"), _premultiplied(background, "background")
    ink = fg + (1.0 - fg[3]) * bg  # foreground over background, premultiplied

    # The glyph mask in font pixels, top row first.
    columns, rows = max(longest, 1), len(text)
    mask = np.zeros((rows * CELL_H - 1, columns * CELL_W - 1), dtype=bool)
    for row, line in enumerate(text):
        for col, char in enumerate(line):
            index = ord(char) - _FIRST
            glyph = _GLYPHS[index if 0 <= index < len(_GLYPHS) else _QUESTION]
            y, x = row * CELL_H, col * CELL_W
            mask[y : y + GLYPH_H, x : x + GLYPH_W] = glyph
    mask = np.repeat(np.repeat(mask, scale, axis=0), scale, axis=1)
    mask = np.pad(mask, padding)[::-1]  # row 0 = bottom
    image = np.where(mask[..., None], ink, bg)
    return image.astype(np.float32)


def hud_quad(
    eye_offset_m: float,
    aspect: float,
    distance_m: float = 1.2,
    height_m: float = 0.18,
    below_m: float = 0.25,
) -> np.ndarray:
    """``(4, 3)`` float64 view-space corners of the HUD quad in this eye's view space: bottom-left,
    bottom-right, top-left, top-right (t = 0 along the bottom edge, s = 0 along the left).

    The quad is ``height_m`` high and ``aspect`` · ``height_m`` wide (``aspect``: the image's
    width / height, so the text keeps its shape), ``distance_m`` in front of the viewer (−z),
    centred horizontally on the HEAD (the point between the eyes) with its centre ``below_m``
    under the eye line. ``eye_offset_m`` is this eye's offset from the head centre along
    view-space +x (left eye −ipd/2, right eye +ipd/2, mono 0): the corners shift by
    −``eye_offset_m`` so both eyes see one quad fixed to the head, with the disparity of an
    object at ``distance_m``. Assumes the eyes look parallel to the head's forward axis (no
    canted displays), as OpenXR's views of the usual headsets do."""
    for name, value in (("aspect", aspect), ("distance_m", distance_m), ("height_m", height_m)):
        if not np.isfinite(value) or value <= 0.0:
            raise ValueError(f"{name} must be a positive number, got {value!r}")
    half_w, half_h = 0.5 * aspect * height_m, 0.5 * height_m
    x0, x1 = -half_w - eye_offset_m, half_w - eye_offset_m
    y0, y1 = -below_m - half_h, -below_m + half_h
    z = -distance_m
    return np.array([[x0, y0, z], [x1, y0, z], [x0, y1, z], [x1, y1, z]], dtype=np.float64)

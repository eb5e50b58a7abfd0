"""The VR HUD's bpy-free parts (render/hud.py): status text, the bitmap-font raster, the quad."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.render.hud import (
    MAX_CHARS,
    MAX_LINES,
    hud_quad,
    raster_text,
    status_lines,
)

CLEAR = (0.0, 0.0, 0.0, 0.0)


def ink(lines, **kwargs) -> np.ndarray:
    """(h, w) bool glyph mask, TOP row first (reading order), scale 1, no padding."""
    image = raster_text(lines, scale=1, padding=0, background=CLEAR, **kwargs)
    return image[::-1, :, 3] > 0.5


def picture(art: str) -> np.ndarray:
    return np.array([[c == "#" for c in row] for row in art.split()])


# The font's 'L', 'I' and 'g' as drawn (5 × 8, top row first, the last row below the baseline).
L_ART = "#.... #.... #.... #.... #.... #.... ##### ....."
I_ART = ".###. ..#.. ..#.. ..#.. ..#.. ..#.. .###. ....."
G_ART = "..... ..... .#### #...# #...# .#### ....# .###."


def test_size_shape_and_dtype():
    image = raster_text(["abcd", "e"], scale=2, padding=4)
    # w = 2·4 + 2·(6·4 − 1), h = 2·4 + 2·(9·2 − 1): 6 × 9 cells less the trailing spacing.
    assert image.shape == (8 + 2 * 17, 8 + 2 * 23, 4)
    assert image.dtype == np.float32
    assert raster_text([], padding=0).shape == (2 * 8, 2 * 5, 4)  # never empty: one blank cell


def test_pixels_are_premultiplied_foreground_over_background():
    fg, bg = (1.0, 0.5, 0.25, 0.8), (0.2, 0.4, 0.6, 0.5)
    image = raster_text(["Hi!"], foreground=fg, background=bg).reshape(-1, 4)
    bg_p = np.array([0.1, 0.2, 0.3, 0.5])
    fg_p = np.array([0.8, 0.4, 0.2, 0.8])
    ink_p = fg_p + (1 - 0.8) * bg_p  # over: (0.82, 0.44, 0.26, 0.9)
    values = np.unique(image, axis=0)  # exactly two pixel values: background and ink
    # 1e-7: float32 rounding of values below 1
    np.testing.assert_allclose(values, [bg_p, ink_p], atol=1e-7)  # unique sorts rows
    assert np.all(image[:, :3] <= image[:, 3:] + 1e-7)  # premultiplied: colour ≤ alpha
    np.testing.assert_allclose(image[0], bg_p, atol=1e-7)  # a padding pixel


def test_known_glyphs_read_upright_and_unmirrored():
    """Row 0 of the raster is the bottom: flipped, the glyphs read as drawn, and the 'L' has
    its bar at the bottom and its stem at the left (no mirror, no flip)."""
    np.testing.assert_array_equal(ink(["L"]), picture(L_ART))
    np.testing.assert_array_equal(ink(["I"]), picture(I_ART))
    np.testing.assert_array_equal(ink(["g"]), picture(G_ART))  # descender in the last row
    raw = raster_text(["L"], scale=1, padding=0, background=CLEAR)[..., 3] > 0.5
    assert raw[1].all()  # row 1 from the bottom (row 0 is the descender row) is L's bar


def test_characters_sit_in_cells_with_spacing():
    mask = ink(["IL", "gI"])
    assert mask.shape == (17, 11)
    np.testing.assert_array_equal(mask[:8, 0:5], picture(I_ART))
    np.testing.assert_array_equal(mask[:8, 6:11], picture(L_ART))
    np.testing.assert_array_equal(mask[9:17, 0:5], picture(G_ART))
    np.testing.assert_array_equal(mask[9:17, 6:11], picture(I_ART))
    assert not mask[:, 5].any() and not mask[8].any()  # the spacing column and row


def test_scale_repeats_font_pixels_and_padding_surrounds():
    one = raster_text(["Ag"], scale=1, padding=0)
    three = raster_text(["Ag"], scale=3, padding=5)
    np.testing.assert_array_equal(three[5:-5, 5:-5], np.kron(one, np.ones((3, 3, 1))))
    background = three[0, 0]
    for border in (three[:5], three[-5:], three[:, :5], three[:, -5:]):
        assert np.all(border == background)


def test_unknown_characters_are_question_marks_and_stand_ins_are_ascii():
    question = ink(["?"])
    for char in ("é", "\t", "\u2603", "\x7f"):
        np.testing.assert_array_equal(ink([char]), question)
    np.testing.assert_array_equal(ink(["a·b × c − d"]), ink(["a.b x c - d"]))
    np.testing.assert_array_equal(ink(["wait…"]), ink(["wait..."]))


def test_limits_are_refused():
    raster_text(["x" * MAX_CHARS] * MAX_LINES, scale=1)  # the largest page is accepted
    with pytest.raises(ValueError, match="lines"):
        raster_text(["x"] * (MAX_LINES + 1))
    with pytest.raises(ValueError, match="characters"):
        raster_text(["x" * (MAX_CHARS + 1)])
    with pytest.raises(ValueError, match="characters"):  # counted after the stand-ins
        raster_text(["…" * (MAX_CHARS // 3 + 1)])
    with pytest.raises(ValueError, match="scale"):
        raster_text(["x"], scale=0)
    with pytest.raises(ValueError, match="padding"):
        raster_text(["x"], padding=-1)
    with pytest.raises(ValueError, match="foreground"):
        raster_text(["x"], foreground=(1.0, 1.0, 1.5, 1.0))
    with pytest.raises(ValueError, match="background"):
        raster_text(["x"], background=(0.0, 0.0, 0.0))
    with pytest.raises(TypeError):
        raster_text("one string")


def test_status_lines():
    assert status_lines("alu", 45, 200, "9.8/11.0 ms, 5 lights per frame") == [
        "alu",
        "lights 45/200",
        "9.8/11.0 ms, 5 lights per frame",
    ]
    assert status_lines("", 0, 200, "") == ["(no BTF material)", "lights 0/200"]
    long = status_lines("m" * 500, 1, 2, "over budget × 2")
    assert len(long[0]) == MAX_CHARS and long[0].endswith("...")
    assert long[2] == "over budget x 2"
    raster_text(long)  # always accepted


IPD = 0.064


def test_hud_quad_is_fixed_to_the_head_for_both_eyes():
    left, right, mono = (hud_quad(s * IPD / 2, 3.0) for s in (-1, 1, 0))
    # One quad in the head's frame: seen from the left eye it lies ipd further right.
    np.testing.assert_allclose(left[:, 0], right[:, 0] + IPD, atol=1e-12)
    np.testing.assert_allclose(left[:, 1:], right[:, 1:], atol=0)
    np.testing.assert_allclose(mono[:, 0].mean(), 0.0, atol=1e-12)  # centred on the head
    np.testing.assert_allclose((left[:, 0] + right[:, 0]) / 2, mono[:, 0], atol=1e-12)


def test_hud_quad_geometry():
    corners = hud_quad(0.0, aspect=2.5, distance_m=1.5, height_m=0.2, below_m=0.3)
    assert corners.shape == (4, 3) and corners.dtype == np.float64
    bl, br, tl, tr = corners
    np.testing.assert_allclose(corners[:, 2], -1.5)  # in front: view space looks down −z
    np.testing.assert_allclose(tl[1] - bl[1], 0.2)  # height
    np.testing.assert_allclose(br[0] - bl[0], 2.5 * 0.2)  # width = aspect · height
    np.testing.assert_allclose((bl[1] + tl[1]) / 2, -0.3)  # centre below the eye line
    assert bl[0] < br[0] and tl[0] < tr[0] and bl[1] == br[1] and tl[1] == tr[1]
    for bad in ({"aspect": 0.0}, {"aspect": np.nan}, {"distance_m": -1.0}, {"height_m": 0.0}):
        with pytest.raises(ValueError):
            hud_quad(0.0, **{"aspect": 2.0, **bad})

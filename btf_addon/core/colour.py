"""Colour transforms used by BTFbase's MLVQ codec ("user colour model" → RGB).

LDR materials store 8-bit studio-swing BT.601 YCbCr; HDR materials store the log-luminance
LogLuv model of Mantiuk et al. 2006 (MPI-I-2005-4-001). Both follow the original decoder
(BTFbase, Havran et al.), including its clamping of negative RGB to zero.
"""

from __future__ import annotations

import numpy as np


def ycbcr_to_rgb(y: np.ndarray, cb: np.ndarray, cr: np.ndarray) -> np.ndarray:
    """Studio-swing BT.601 YCbCr (8-bit scale) → RGB (8-bit scale), negatives clamped.

    y, cb, cr: (...) float arrays. Returns (..., 3) in the inputs' float dtype.
    """
    r = 1.1643828 * y + 1.5960273 * cr - 222.921
    g = 1.1643828 * y - 0.39176172 * cb - 0.81296875 * cr + 135.576
    b = 1.1643828 * y + 2.0172344 * cb - 276.836
    return np.maximum(np.stack([r, g, b], axis=-1), 0.0)


def mantiuk_luminance(l_code: np.ndarray) -> np.ndarray:
    """Mantiuk 2006 luma code → luminance Y (three pieces: linear, power, exponential)."""
    l_code = np.asarray(l_code, dtype=np.float64)
    low = 0.056968 * l_code
    # The power piece overflows only for codes far outside its own interval; clip its input.
    mid = 7.3014e-30 * np.power(np.clip(l_code, 0.0, 1204.7) + 884.17, 9.9872)
    high = 32.994 * np.exp(np.minimum(0.0047811 * l_code, 700.0))
    return np.where(l_code < 98.381, low, np.where(l_code < 1204.7, mid, high))


def srgb_encode(c: np.ndarray) -> np.ndarray:
    """Linear → sRGB transfer curve (as the original HDR decoder applies it)."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(
        c > 0.0031308, 1.055 * np.power(np.maximum(c, 0.0031308), 1.0 / 2.4) - 0.055, 12.92 * c
    )


def srgb_decode(s: np.ndarray) -> np.ndarray:
    """sRGB transfer curve → linear (the inverse of ``srgb_encode``)."""
    s = np.asarray(s, dtype=np.float64)
    return np.where(
        s <= 0.04045, s / 12.92, np.power((np.maximum(s, 0.04045) + 0.055) / 1.055, 2.4)
    )


def logluv_to_rgb(l_code: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Mantiuk LogLuv (luma code, u', v' scaled by 410) → RGB as the BTFbase HDR decoder does.

    Luminance per ``mantiuk_luminance``; chromaticity through XYZ with the D65 sRGB matrix;
    negatives clamped; then the sRGB curve, because the UBO HDR images were gamma corrected
    (the original author's note). Returns (..., 3) float64.
    """
    y = mantiuk_luminance(l_code)
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    positive = v > 0.0
    safe_v = np.where(positive, v, 1.0)
    x = np.where(positive, 9.0 / 4.0 * u / safe_v * y, 0.0)
    z = np.where(positive, y * (3.0 * 410.0 / safe_v - 5.0) - x / 3.0, 0.0)
    r = 3.2406 * x - 1.5372 * y - 0.4986 * z
    g = -0.9689 * x + 1.8758 * y + 0.0415 * z
    b = 0.0557 * x - 0.2040 * y + 1.0570 * z
    rgb = np.maximum(np.stack([r, g, b], axis=-1), 0.0)
    return srgb_encode(rgb)

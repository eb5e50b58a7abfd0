"""The default F12 of the demo at 320 × 240 shows no fireflies (issue 33).

A firefly: a pixel whose luminance exceeds 10× the median of its 3 × 3 neighbourhood. The
issue's count leaves out pixels where a 4096-sample reference is such a pixel too (a true
pinpoint highlight); the default render has none at all, so no reference is needed for the
count to be zero. The criterion is first checked on a constructed image, so a zero means the
counter works. About 10 s (64 samples, 4 bounces, Clamp Indirect 10: the defaults)."""

from __future__ import annotations

import numpy as np
from helpers import run_cli

from btf_addon.core.formats.imageio import read_exr

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def fireflies(image: np.ndarray) -> np.ndarray:
    """(h, w) bool: luminance above 10× the median of the pixel's 3 × 3 neighbourhood."""
    lum = image[..., :3] @ LUMINANCE
    padded = np.pad(lum, 1, mode="edge")
    h, w = lum.shape
    around = np.stack([padded[dy : dy + h, dx : dx + w] for dy in range(3) for dx in range(3)])
    return lum > 10.0 * np.median(around, axis=0)


def test_the_counter_finds_a_lone_bright_pixel_and_not_an_edge():
    image = np.full((8, 8, 3), 0.2)
    image[:, 4:] = 5.0  # an edge: half the neighbourhood is bright, the median with it
    image[2, 1] = 3.0  # a firefly in the dark half
    assert np.argwhere(fireflies(image)).tolist() == [[2, 1]]


def test_the_default_demo_f12_has_no_fireflies(tmp_path):
    out = tmp_path / "demo.exr"
    run_cli("render", "--demo", "--resolution", "320x240", "-o", out)
    image = read_exr(out)
    assert image.shape[:2] == (240, 320) and image[..., :3].mean() > 0.05  # a lit frame
    found = np.argwhere(fireflies(image))
    assert len(found) == 0, f"{len(found)} fireflies, first at rows/columns {found[:10].tolist()}"

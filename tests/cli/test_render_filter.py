"""``render --filter TYPE:WIDTH``: the film's pixel filter from the command line (parsing only:
what F12 does with the filter is tested in tests/kernels and tests/blender)."""

from __future__ import annotations

import argparse

import pytest

from btf_addon.cli.render_command import _pixel_filter
from btf_addon.render.pixel_filter import PixelFilter


def test_filter_flags_parse_to_the_film():
    assert _pixel_filter("gaussian:2") == PixelFilter("GAUSSIAN", 2.0)
    assert _pixel_filter("BLACKMAN_HARRIS:1.5") == PixelFilter()
    assert _pixel_filter("box") == PixelFilter("BOX", 1.5)  # Blender's default width
    assert _pixel_filter("none") is None  # pixel centres


@pytest.mark.parametrize("text", ["mitchell:1", "box:-1", "gaussian:wide"])
def test_bad_filters_name_the_choices(text):
    with pytest.raises(argparse.ArgumentTypeError, match="box, gaussian, blackman_harris"):
        _pixel_filter(text)

"""An eye's swapchain size keeps the runtime's recommended aspect whatever the scale and the
runtime's maximum (issue 30 item 7: Monado recommends 4:3; clamping each side alone made it
16:9 at --scale 10). bpy- and runtime-free: the rule itself, then the session's use of it."""

import ast

import pytest
from helpers import ROOT

from btf_addon.xr.views import swapchain_size


@pytest.mark.parametrize(
    ("recommended", "maximum", "scale", "expected"),
    [
        ((1440, 1080), (3840, 2160), 10.0, (2880, 2160)),  # the height binds: 4:3 kept
        ((1440, 1080), (3840, 2160), 1.0, (1440, 1080)),
        ((1440, 1080), (3840, 2160), 0.5, (720, 540)),
        ((1440, 1080), (0, 0), 3.0, (1440, 1080)),  # no maximum stated: recommended is the most
        ((2016, 2240), (8064, 8960), 2.0, (4032, 4480)),
        ((7, 5), (10, 100), 100.0, (10, 7)),  # the width binds, rounded
        ((100, 100), (100, 100), 1e-6, (1, 1)),  # at least one pixel a side
    ],
)
def test_one_factor_for_both_sides(recommended, maximum, scale, expected):
    w, h = swapchain_size(recommended, maximum, scale)
    assert (w, h) == expected
    # The aspect within a pixel of rounding on the shorter side (unless clamped to 1 pixel).
    if min(w, h) > 1:
        assert abs(w / h - recommended[0] / recommended[1]) <= 1.0 / min(w, h) + 1e-12


def test_the_session_sizes_swapchains_by_that_rule():
    """The session's swapchain creation calls swapchain_size and clamps no side on its own."""
    source = (ROOT / "btf_addon" / "xr" / "session.py").read_text()
    calls = [
        node.func.id
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
    ]
    assert "swapchain_size" in calls
    assert "* self.resolution_scale" not in source

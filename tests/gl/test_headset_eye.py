"""One headset eye for both VR paths (gl/eye.py ``HeadsetEye``): its frame budget, fixed K and
HUD refresh on moderngl with an injected clock, and that Blender's VR session callback
(blender/vr/preview.py) and the XTAL bridge (xr/bridge.py) keep no eye, HUD text or refresh
period of their own. Their images and HUDs through it are checked by tests/xr/test_bridge.py
and tests/blender/test_xr_draw.py."""

from __future__ import annotations

import ast
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import ROOT

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.headsets import profile, stereo_eyes
from btf_addon.render.hud import MAX_CHARS, MAX_LINES
from btf_addon.render.settings import RenderSettings
from btf_addon.scene.primitives import uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

#: The VR paths and the one module that may make an eye's parts.
PATHS = ("btf_addon/blender/vr/preview.py", "btf_addon/xr/bridge.py")
EYE_MODULE = "btf_addon/gl/eye.py"
EYE_PARTS = {"FrameBudget", "HudDrawer", "EyeAccumulation", "status_lines", "raster_text"}


@pytest.fixture
def drawer(gl_ctx):
    from btf_addon.gl.drawer import ProgressiveDrawer
    from btf_addon.gl.moderngl_device import ModernGLDevice

    scene = Scene(
        [uv_sphere(1.0, segments=16, rings=8)],
        [Material(LambertianBTF(0.6), name="Felt")],
        Camera(look_at((0.0, -4.0, 0.0), (0.0, 0.0, 0.0))),
        Environment(np.full((8, 16, 3), 0.5, dtype=np.float32)),
    )
    drawer = ProgressiveDrawer(ModernGLDevice(gl_ctx), scene)
    yield drawer
    drawer.release()


@pytest.fixture
def left_eye():
    """A headset's left eye looking at the sphere, 64 × 48 pixels."""
    headset = profile("simulated").scaled(0.2)
    return stereo_eyes(headset, look_at((0.0, -4.0, 0.0), (0.0, 0.0, 0.0)))[0]


def new_eye(drawer, clock, budget_s=0.011):
    from btf_addon.gl.eye import HeadsetEye

    return HeadsetEye(drawer.device, budget_s, clock)


def frame(eye, drawer, left_eye, k, lights_total=4096):
    settings = RenderSettings(lights_total=lights_total, use_antialiasing=False)
    size = (left_eye.width, left_eye.height)
    return eye.advance(drawer, size, settings, left_eye.clip_from_view, left_eye.view_from_world, k)


def test_the_budget_picks_k_from_the_eyes_own_intervals(drawer, left_eye):
    """A clock advancing 2 ms + 3 ms per light the eye drew: the 11 ms budget holds
    floor((11 − 2) / 3) = 3 lights per frame; a budget passed per frame (the bridge's runtime
    period) is held from then on, None keeps it."""
    clock = SimpleNamespace(t=0.0)
    eye = new_eye(drawer, lambda: clock.t)
    try:
        for _ in range(30):
            clock.t += 0.002 + 0.003 * eye.drawn
            k = eye.lights_this_frame()
            assert eye.drawn == 0  # measured: the next interval is this frame's
            frame(eye, drawer, left_eye, k)
            assert eye.drawn == k
        assert eye.budget.lights_per_frame == 3 and not eye.budget.over_budget
        assert eye.status() == eye.budget.status()
        for _ in range(30):
            clock.t += 0.002 + 0.003 * eye.drawn
            frame(eye, drawer, left_eye, eye.lights_this_frame(budget_s=0.0201))
        assert eye.budget.budget_s == 0.0201 and eye.budget.lights_per_frame == 6
        eye.lights_this_frame(budget_s=None)
        assert eye.budget.budget_s == 0.0201
    finally:
        eye.release()


def test_a_fixed_k_leaves_the_budget_alone(drawer, left_eye):
    clock = SimpleNamespace(t=0.0)
    eye = new_eye(drawer, lambda: clock.t)
    try:
        for _ in range(3):
            clock.t += 0.5
            k = eye.lights_this_frame(lights_per_frame=7)
            frame(eye, drawer, left_eye, k)
        assert k == 7 and eye.view.state.done == 21
        assert eye.budget.frame_time_s is None  # no interval was fed to it
        assert eye.status() == "7 lights/frame"
    finally:
        eye.release()


def test_the_hud_text_refreshes_every_hud_refresh_s_and_when_converged(drawer, left_eye):
    """Within HUD_REFRESH_S the text (and its texture) stays, however many lights came in;
    after it, the text follows; once the eye converges it shows the last lights at once."""
    from btf_addon.gl.eye import HUD_REFRESH_S

    clock = SimpleNamespace(t=0.0)
    eye = new_eye(drawer, lambda: clock.t)
    target = drawer.device.target(left_eye.width, left_eye.height, "RGBA32F", depth=False)

    def hud_frame(dt, lights_total=4096, extra=()):
        clock.t += dt
        frame(eye, drawer, left_eye, eye.lights_this_frame(3), lights_total)
        with drawer.device.bound(target):
            eye.draw_hud(left_eye.clip_from_view, -0.032, "Felt", extra)
        return list(eye.hud_lines)

    try:
        assert hud_frame(0.0) == ["Felt", "lights 3/4096", "3 lights/frame"]
        assert eye.hud.uploads == 1
        assert hud_frame(0.4 * HUD_REFRESH_S)[1] == "lights 3/4096"  # 6 in, not shown yet
        assert eye.hud.uploads == 1
        assert hud_frame(0.7 * HUD_REFRESH_S)[1] == "lights 9/4096"
        assert eye.hud.uploads == 2
        # Extra lines (the Wiimote's help) follow the status, cut to the HUD's page.
        long_lines = ["x" * (MAX_CHARS + 10)] * MAX_LINES
        lines = hud_frame(HUD_REFRESH_S, extra=long_lines)
        assert len(lines) == MAX_LINES and lines[3] == "x" * MAX_CHARS
        # New lights (N = 6): within the refresh period the text stays, until they converge.
        assert hud_frame(0.1 * HUD_REFRESH_S, lights_total=6)[1] == "lights 12/4096"
        assert hud_frame(0.1 * HUD_REFRESH_S, lights_total=6)[1] == "lights 6/6"
        assert eye.view.state.converged
    finally:
        drawer.device.release(target)
        eye.release()
    assert eye.hud is None and eye.view is None


def test_the_hud_keeps_its_size_in_the_headset_at_any_navigation_scale(drawer, left_eye):
    """Blender's VR navigation scale s puts the quad s times further in scene units (and the
    eye s times further from the head's centre): the eye sees the same pixels."""
    eye = new_eye(drawer, lambda: 0.0)
    device = drawer.device
    target = device.target(left_eye.width, left_eye.height, "RGBA32F", depth=False)
    images = []
    try:
        frame(eye, drawer, left_eye, eye.lights_this_frame(1))
        for scale in (1.0, 4.0):
            with device.bound(target):
                device.clear((0.0, 0.0, 0.0, 0.0))
                if scale == 1.0:
                    eye.draw_hud(left_eye.clip_from_view, -0.032, "Felt")
                else:
                    eye.draw_hud_image(left_eye.clip_from_view, -0.032 * scale, scale)
            images.append(device.read(target))
    finally:
        device.release(target)
        eye.release()
    assert images[0][..., 3].max() > 0.5  # the HUD is there
    np.testing.assert_allclose(images[1], images[0], atol=1e-4)


def _tree(path: str) -> ast.Module:
    return ast.parse((ROOT / path).read_text())


def _called(tree: ast.AST) -> set[str]:
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            names.add(func.id if isinstance(func, ast.Name) else getattr(func, "attr", ""))
    return names


@pytest.mark.parametrize("path", PATHS)
def test_both_vr_paths_use_the_one_headset_eye(path):
    """Before, preview.py had ``EyeState`` and bridge.py ``_Eye``, each with its own
    ``_draw_hud`` and ``HUD_REFRESH_S``: their HUD texts and refresh drifted apart."""
    tree = _tree(path)
    classes = [n.name for n in ast.walk(tree) if isinstance(n, ast.ClassDef)]
    assert not [name for name in classes if "eye" in name.lower()], classes
    functions = {
        n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)
    }
    assert not {"_draw_hud", "draw_hud"} & functions
    assigned = {
        target.id
        for node in ast.walk(tree)
        if isinstance(node, ast.Assign | ast.AnnAssign)
        for target in (node.targets if isinstance(node, ast.Assign) else [node.target])
        if isinstance(target, ast.Name)
    }
    assert "HUD_REFRESH_S" not in assigned
    assert "HeadsetEye" in _called(tree)


def test_only_the_headset_eye_makes_an_eyes_parts():
    """A second eye object would make its own budget, HUD drawer, accumulation or HUD text."""
    makers = {}
    for path in sorted((ROOT / "btf_addon").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel in (EYE_MODULE, "btf_addon/render/hud.py", "btf_addon/render/accuracy/plot.py"):
            continue  # the eye itself; the font's own module; the plots' text (not an eye's)
        made = _called(ast.parse(path.read_text())) & EYE_PARTS
        if made:
            makers[rel] = sorted(made)
    assert makers == {}

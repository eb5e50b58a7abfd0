"""The VR HUD drawn through the Device protocol (gl/hud.py): on moderngl (EGL) in-process, and
once on Blender's gpu module (its create-info build and ALPHA_PREMULT blend) in a subprocess.

Every draw goes into an RGBA32F target, so the blend is checked in float, not in 8 bits."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from helpers import ROOT

from btf_addon.render.hud import hud_quad, raster_text

W, H = 96, 80
IPD = 0.064
# A quad larger than the HUD's default so the checks see many pixels: 1.0 m × 0.5 m at 1.2 m.
QUAD = {"aspect": 2.0, "distance_m": 1.2, "height_m": 0.5, "below_m": 0.1}
PREMULTIPLIED = np.array([0.9 * 0.6, 0.5 * 0.6, 0.1 * 0.6, 0.6], dtype=np.float32)
BACKGROUND = (0.1, 0.2, 0.3, 0.5)  # not opaque: the alpha channel's blend is checked too


def perspective(fov_y_deg: float, aspect: float, near: float = 0.1, far: float = 100.0):
    """OpenGL's symmetric perspective (clip from view), written out here, independent of the
    add-on's camera code."""
    f = 1.0 / np.tan(np.radians(fov_y_deg) / 2.0)
    return np.array(
        [
            [f / aspect, 0.0, 0.0, 0.0],
            [0.0, f, 0.0, 0.0],
            [0.0, 0.0, (far + near) / (near - far), 2.0 * far * near / (near - far)],
            [0.0, 0.0, -1.0, 0.0],
        ]
    )


CLIP_FROM_VIEW = perspective(60.0, W / H)


def projected_rectangle(corners: np.ndarray) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) in pixels (y up, as ``read`` returns rows) of the quad's corners."""
    clip = np.c_[corners, np.ones(4)] @ CLIP_FROM_VIEW.T
    ndc = clip[:, :2] / clip[:, 3:]
    px = (ndc[:, 0] + 1.0) * 0.5 * W
    py = (ndc[:, 1] + 1.0) * 0.5 * H
    return px.min(), px.max(), py.min(), py.max()


def check_coverage(covered: np.ndarray, corners: np.ndarray) -> None:
    """Pixels whose centre is inside the projected rectangle are covered, others not, except
    within 1 px of its edges (rasterisation rules and rounding at the boundary)."""
    x0, x1, y0, y1 = projected_rectangle(corners)
    xs, ys = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    inside = (xs > x0) & (xs < x1) & (ys > y0) & (ys < y1)
    near_edge = ((np.abs(xs - x0) <= 1) | (np.abs(xs - x1) <= 1) | (np.abs(ys - y0) <= 1)) | (
        np.abs(ys - y1) <= 1
    )
    wrong = (covered != inside) & ~near_edge
    assert not wrong.any(), f"{wrong.sum()} pixels off the projected rectangle {x0, x1, y0, y1}"
    assert inside.sum() > 500  # the check sees a real area, not a sliver


def check_blend(pixels: np.ndarray, corners: np.ndarray) -> None:
    """Inside (2 px from the edges): premultiplied over, src + dst·(1 − src_a), colour and alpha;
    outside: the cleared background untouched. 1e-5: float32 blending in an RGBA32F target and
    linear filtering of a constant texture (weights summing to 1 up to float rounding)."""
    x0, x1, y0, y1 = projected_rectangle(corners)
    xs, ys = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    deep = (xs > x0 + 2) & (xs < x1 - 2) & (ys > y0 + 2) & (ys < y1 - 2)
    outside = (xs < x0 - 2) | (xs > x1 + 2) | (ys < y0 - 2) | (ys > y1 + 2)
    expected = PREMULTIPLIED + np.array(BACKGROUND) * (1.0 - PREMULTIPLIED[3])
    np.testing.assert_allclose(pixels[deep], np.broadcast_to(expected, (deep.sum(), 4)), atol=1e-5)
    np.testing.assert_allclose(
        pixels[outside], np.broadcast_to(BACKGROUND, (outside.sum(), 4)), atol=1e-6
    )


@pytest.fixture
def device(gl_ctx):
    from btf_addon.gl.moderngl_device import ModernGLDevice

    return ModernGLDevice(gl_ctx)


def draw_hud(device, image: np.ndarray, corners: np.ndarray, background=(0.0, 0.0, 0.0, 0.0)):
    from btf_addon.gl.hud import HudDrawer

    hud = HudDrawer(device)
    target = device.target(W, H, "RGBA32F", depth=True)
    try:
        hud.set_image(image)
        with device.bound(target):
            device.clear(background)
            hud.draw(CLIP_FROM_VIEW, corners)
        return device.read(target)
    finally:
        hud.release()
        device.release(target)


@pytest.mark.parametrize("eye_offset", [-IPD / 2, 0.0, IPD / 2])
def test_the_quad_covers_its_projected_corners(device, eye_offset):
    corners = hud_quad(eye_offset, **QUAD)
    pixels = draw_hud(device, np.ones((8, 16, 4), dtype=np.float32), corners)
    check_coverage(pixels[..., 3] > 0.5, corners)


def test_the_right_eye_sees_the_quad_further_left(device):
    """Disparity of an object in front: its image is further left in the right eye, by
    ipd·(projection's x scale)·W/2 / distance pixels."""
    solid = np.ones((8, 16, 4), dtype=np.float32)
    lefts = []
    for offset in (-IPD / 2, IPD / 2):
        covered = draw_hud(device, solid, hud_quad(offset, **QUAD))[..., 3] > 0.5
        columns = np.flatnonzero(covered.any(axis=0))
        lefts.append(columns[0])
    expected = IPD * CLIP_FROM_VIEW[0, 0] * W / 2 / QUAD["distance_m"]  # ≈ 3.0 px
    assert abs((lefts[0] - lefts[1]) - expected) <= 1, (lefts, expected)


def test_blending_is_premultiplied_over(device):
    corners = hud_quad(0.0, **QUAD)
    image = np.broadcast_to(PREMULTIPLIED, (8, 16, 4)).copy()
    check_blend(draw_hud(device, image, corners, BACKGROUND), corners)


def test_text_is_upright_and_not_mirrored(device):
    """Ink only in the top-left quarter of the raster (one 'I' over an empty line, then a
    space) lands in the top-left quarter of the drawn quad."""
    image = raster_text(["I ", "  "], scale=2, background=(0, 0, 0, 0), padding=0)
    corners = hud_quad(0.0, aspect=image.shape[1] / image.shape[0], distance_m=1.2, height_m=0.5)
    pixels = draw_hud(device, image, corners)
    x0, x1, y0, y1 = projected_rectangle(corners)
    ys, xs = np.nonzero(pixels[..., 3] > 0.5)  # row 0 = bottom
    assert len(xs) > 20
    assert xs.max() + 0.5 < (x0 + x1) / 2, "ink right of the middle: mirrored"
    assert ys.min() + 0.5 > (y0 + y1) / 2, "ink below the middle: upside down"


class CountingDevice:
    """The real moderngl device, counting texture uploads."""

    def __init__(self, device):
        self.inner, self.textures = device, 0

    def texture(self, array, **kwargs):
        self.textures += 1
        return self.inner.texture(array, **kwargs)

    def __getattr__(self, name):
        return getattr(self.inner, name)


def test_set_image_uploads_only_changed_pixels(device):
    from btf_addon.gl.hud import HudDrawer

    counting = CountingDevice(device)
    hud = HudDrawer(counting)
    try:
        image = raster_text(["lights 45/200"])
        hud.set_image(image)
        first = hud.texture
        hud.set_image(image.copy())  # equal pixels, another array
        hud.set_image(raster_text(["lights 45/200"]))
        assert counting.textures == hud.uploads == 1 and hud.texture is first
        changed = image.copy()
        changed[0, 0, 0] += 0.25
        hud.set_image(changed)
        assert counting.textures == hud.uploads == 2 and hud.texture is not first
        hud.set_image(raster_text(["lights 46/200"]))
        # Same bytes, another shape: still a new image.
        flat = np.ones((4, 8, 4), dtype=np.float32)
        hud.set_image(flat)
        hud.set_image(flat.reshape(8, 4, 4))
        assert counting.textures == hud.uploads == 5
        assert hud.image_size == (4, 8)
    finally:
        hud.release()


def test_draw_before_an_image_and_bad_shapes_are_refused(device):
    from btf_addon.gl.hud import HudDrawer

    hud = HudDrawer(device)
    try:
        with pytest.raises(RuntimeError, match="set_image"):
            hud.draw(CLIP_FROM_VIEW, hud_quad(0.0, 2.0))
        with pytest.raises(ValueError, match=r"\(h, w, 4\)"):
            hud.set_image(np.ones((4, 4, 3), dtype=np.float32))
        hud.set_image(np.ones((4, 4, 4), dtype=np.float32))
        with pytest.raises(ValueError, match="corners"):
            hud.draw(CLIP_FROM_VIEW, np.zeros((3, 3)))
    finally:
        hud.release()


_BLENDER_SCRIPT = """
import sys
sys.path[:0] = [{root!r}, {tests!r}]
import bpy
import numpy as np
from blender_helpers import init_gpu_module

init_gpu_module(bpy)  # background Blender draws with gpu only after one render
from btf_addon.blender.compat import exit_python
from btf_addon.blender.gpu_draw import BlenderGPUDevice
from btf_addon.gl.hud import HudDrawer

device = BlenderGPUDevice()
hud = HudDrawer(device)  # builds HUD_SHADER through blender_create_info()
target = device.target({w}, {h}, "RGBA32F", True)
hud.set_image(np.load({image!r}))
with device.bound(target):
    device.clear({background!r})
    hud.draw(np.load({clip!r}), np.load({corners!r}))
np.save({out!r}, device.read(target))
hud.release()
device.release(target)
exit_python(0)
"""


@pytest.mark.blender
def test_blender_gpu_module_draws_the_same_hud(tmp_path):
    """The HUD through Blender's gpu adapter (create-info shader, ALPHA_PREMULT): the same
    coverage and the same premultiplied blend as on moderngl. A subprocess, so bpy never shares
    this process with the EGL context of the other GL tests."""
    pytest.importorskip("bpy", reason="Blender as a Python module (pip install bpy==5.0.1)")
    corners = hud_quad(IPD / 2, **QUAD)
    paths = {name: str(tmp_path / f"{name}.npy") for name in ("image", "clip", "corners", "out")}
    np.save(paths["image"], np.broadcast_to(PREMULTIPLIED, (8, 16, 4)).copy())
    np.save(paths["clip"], CLIP_FROM_VIEW)
    np.save(paths["corners"], corners)
    script = _BLENDER_SCRIPT.format(
        root=str(ROOT), tests=str(ROOT / "tests"), w=W, h=H, background=BACKGROUND, **paths
    )
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(tmp_path / "user")}
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    pixels = np.load(paths["out"])
    assert pixels.shape == (H, W, 4)
    check_coverage(pixels[..., 3] > 0.75, corners)  # drawn: α 0.8, background: α 0.5
    check_blend(pixels, corners)

"""Images the OpenGL driver cannot hold are a DeviceError (exit 2: a smaller size works), not
a moderngl error deep in a draw (issue 30 item 13: `render --stereo --eye-width 16384`
passed the up-front check and failed with "framebuffer is not complete", exit 1). A side
beyond the driver's texture limit is refused before anything is allocated; a target the driver
refuses anyway (llvmpipe takes no texture over 1 GiB) is named with its size."""

from __future__ import annotations

import pytest

from btf_addon.core.errors import DeviceError
from btf_addon.gl.drawer import ViewAccumulation
from btf_addon.gl.moderngl_device import ModernGLDevice


@pytest.fixture
def device():
    device = ModernGLDevice()
    yield device
    device.close()


def test_a_side_beyond_the_drivers_limit_is_refused_before_allocation(device, monkeypatch):
    allocated = []
    real_texture = device.ctx.texture
    monkeypatch.setattr(
        device.ctx, "texture", lambda *a, **k: allocated.append(a) or real_texture(*a, **k)
    )
    device.max_target_size = 64
    with pytest.raises(DeviceError, match="65×10 is larger than the OpenGL driver's 64 pixels"):
        ViewAccumulation(device, 65, 10)
    assert allocated == []
    ViewAccumulation(device, 64, 10).release()  # at the limit: drawn


def test_a_target_the_driver_refuses_is_named_and_nothing_leaks(device, monkeypatch):
    textures = []
    real_texture = device.ctx.texture

    def texture(*args, **kwargs):
        textures.append(real_texture(*args, **kwargs))
        return textures[-1]

    def refuse(*args, **kwargs):
        import moderngl

        raise moderngl.Error("the framebuffer is not complete (INCOMPLETE_ATTACHMENT)")

    monkeypatch.setattr(device.ctx, "texture", texture)
    monkeypatch.setattr(device.ctx, "framebuffer", refuse)
    with pytest.raises(
        DeviceError, match=r"refuses a 40×30 RGBA32F image \(0\.0 GiB: the framebuffer"
    ):
        device.target(40, 30, "RGBA32F", depth=True)
    assert textures and all(type(t.mglo).__name__ == "InvalidObject" for t in textures)

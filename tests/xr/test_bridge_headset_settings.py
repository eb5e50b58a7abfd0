"""The bridge's eyes take the headset settings Blender's VR session takes (gl/eye.py
``HeadsetSettings``): a fixed K as well as the frame budget's, against the OpenXR test runtime.
Before, the bridge could only follow its budget; ``scene.btf_bridge`` now offers "Fixed" as
``scene.btf_vr`` does."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.settings import RenderSettings
from btf_addon.scene.primitives import uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at


def sphere() -> Scene:
    return Scene(
        [uv_sphere(1.0, segments=12, rings=6)],
        [Material(LambertianBTF(0.5))],
        Camera(look_at((0.0, -4.0, 0.0), (0.0, 0.0, 0.0))),
        Environment(np.full((8, 16, 3), 0.5, dtype=np.float32)),
    )


def test_a_fixed_k_is_what_each_eye_adds_per_frame(xr_runtime):
    from btf_addon.xr.bridge import BridgeSettings, run_bridge

    xr_runtime.script(eye_size=[24, 18])
    options = BridgeSettings(lights_per_frame=3, lights_total=64, show_hud=False, converge=True)
    status = run_bridge(sphere(), RenderSettings(), options, frames=2)
    assert status.lights_per_frame == {"left": 3, "right": 3}
    assert status.lights_done == {"left": 6, "right": 6}


def test_a_fixed_k_below_one_is_refused():
    from btf_addon.xr.bridge import BridgeSettings, XRBridge

    with pytest.raises(ValueError, match="lights_per_frame"):
        XRBridge(sphere(), RenderSettings(), BridgeSettings(lights_per_frame=0))

"""The one place that turns Blender's data into the plain values the render drivers read
(Cycles' ``blender/sync.cpp`` habit): the frame size, the render settings with the scene's film
filter, the VR session's and the XTAL bridge's settings (the headset's part of both from one
reader, blender/vr/headset_settings.py).

Every entry point reads them here — F12, the viewport, Blender's VR session, the XTAL bridge
operator and its CLI, stereo captures, the accuracy report, ``render`` — so one scene gives
every path the same settings and the same size (tests/blender/test_sync.py). Before, the
frame size was computed in five places with two formulas (Blender's integer rule and a float
one that is a pixel short for 198 (resolution, percentage) pairs below 4000), and the bridge
read ``scene.btf_render`` without the film filter that F12 and the VR session honour.
"""

from __future__ import annotations

from ..render.settings import RenderSettings


def frame_size(render) -> tuple[int, int]:
    """The frame in pixels as Blender computes it: ``resolution × percentage // 100`` in
    integers (render_pipeline's ``BKE_render_resolution``), at least 1 pixel a side. A float
    product truncated differs: 100 px at 29 % is 29 here, 28 as ``int(100 * 0.29)``."""
    pct = render.resolution_percentage
    return (
        max(1, render.resolution_x * pct // 100),
        max(1, render.resolution_y * pct // 100),
    )


def render_settings(scene) -> RenderSettings:
    """``scene.btf_render`` with the film filter of ``scene.cycles`` (Blender's default,
    Blackman-Harris 1.5 px, where the Cycles add-on is off)."""
    return RenderSettings.from_scene(scene)


def vr_settings(scene):
    """Blender's VR session's settings (``scene.btf_vr``) as its draw callback reads them."""
    from .vr.headset_settings import headset_values
    from .vr.preview import VRSettings

    props = scene.btf_vr
    return VRSettings(**headset_values(props), show_world=props.show_world)


def bridge_settings(scene):
    """The XTAL bridge's settings (``scene.btf_bridge``) as the bridge reads them: the
    headset's (``headset_values``, as the VR session's) and the bridge's own."""
    from ..xr.bridge import BridgeSettings
    from .vr.headset_settings import headset_values

    props = scene.btf_bridge
    return BridgeSettings(
        **headset_values(props),
        resolution_scale=props.resolution_scale,
        profile=props.profile,
        placement="camera",  # the head starts at the scene camera, as in Blender's VR session
    )

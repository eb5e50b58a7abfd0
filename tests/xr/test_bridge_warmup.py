"""Why the bridge's first frames are slow, said by the bridge (issue 30 item 7): the start
(OpenXR session and GL context, shader compiles, uploads) and the first frames (the driver's
first draws) in ``BridgeStatus.warmup``, the log and, while warming up, the status message."""

from __future__ import annotations

import logging
import re

import numpy as np

from btf_addon.gl.device import DrawState
from btf_addon.render.settings import RenderSettings
from btf_addon.xr.bridge_device import COMPILE, FIRST_DRAWS, UPLOADS, BridgeDevice


class TickingClock:
    """One second per reading: every timed call takes exactly 1 s."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        self.t += 1.0
        return self.t


def test_the_device_sums_compiles_uploads_and_first_draws(gl_ctx):
    from btf_addon.gl.drawer import RESOLVE_SHADER

    device = BridgeDevice(gl_ctx, TickingClock())
    program = device.program(RESOLVE_SHADER)
    assert device.program(RESOLVE_SHADER) is program  # compiled once: timed once
    device.texture(np.zeros((2, 2, 4), dtype=np.float32))
    quad = device.vertices(program, {"pos": np.zeros((3, 2), dtype=np.float32)})
    assert device.take_spent() == {COMPILE: 1.0, UPLOADS: 2.0}
    target = device.target(4, 4, "RGBA32F", False)
    with device.bound(target):
        for state in (DrawState(), DrawState(), DrawState(blend="ADD")):
            device.set_state(state)
            device.draw(program, quad, {}, {})
    assert device.take_spent() == {FIRST_DRAWS: 2.0}  # a new (program, state) pair each
    assert device.take_spent() == {}
    device.release(target, quad)


def test_the_start_and_first_frames_are_explained(xr_runtime, rng, caplog):
    from btf_addon.xr.bridge import WARMUP_FRAMES, run_bridge
    from tests.xr.test_bridge import script, settings, small_scene

    script(xr_runtime, capture_dir=None)
    with caplog.at_level(logging.INFO, logger="btf_addon.xr.bridge"):
        status = run_bridge(small_scene(rng), RenderSettings(), settings(), frames=5)
    lines = status.warmup
    assert re.fullmatch(
        r"start: \d+\.\d\d s \(OpenXR session and GL context \d+\.\d\d s.*\)", lines[0]
    )
    for n in range(1, WARMUP_FRAMES + 1):
        assert re.match(rf"frame {n}: \d+\.\d\d s", lines[n]), lines
    assert len(lines) == 1 + WARMUP_FRAMES  # later frames compile and upload nothing
    logged = [r.getMessage() for r in caplog.records]
    assert all(line in logged for line in lines)
    assert "warming up" not in status.message  # over by the end


def test_the_status_says_warming_up_meanwhile(xr_runtime, rng):
    from btf_addon.xr.bridge import XRBridge
    from tests.xr.test_bridge import script, settings, small_scene

    script(xr_runtime, capture_dir=None)
    bridge = XRBridge(small_scene(rng), RenderSettings(), settings())
    messages = []
    real_publish = bridge._publish

    def publish(*args):
        real_publish(*args)
        messages.append(bridge.status.message)

    bridge._publish = publish
    bridge.start()
    try:
        while bridge.frames < 5:
            assert bridge.run_frame()
    finally:
        bridge.close()
    assert messages[0].startswith("warming up: opening the OpenXR session")
    assert any(m.startswith("warming up: compiling shaders, uploading the scene") for m in messages)
    assert any(m.startswith("warming up: start: ") for m in messages)
    assert any(m.startswith("warming up: frame 1: ") for m in messages)
    assert not messages[-1].startswith("warming up")

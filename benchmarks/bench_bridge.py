"""XTAL bridge (issue 12): the bridge's whole frame loop through the real OpenXR loader and the
OpenXR test runtime (tests/xr_runtime: xrWaitFrame/BeginFrame/LocateViews, per eye
acquire/wait/draw/release, xrEndFrame with its readback of both eyes), on Mesa llvmpipe.

- Cost: submitted frames with a moving head (each eye restarts: World, depth pre-pass, K
  lights, resolve into the sRGB swapchain image) for K = 1, 5, 20 lights per frame pinned, at
  two small eye sizes; mean frame time over a few frames after a warm-up; frame time =
  overhead + cost · K fitted per eye size by least squares, divided by the two eyes' pixels.
  The overhead includes the test runtime's readback of both eyes (a real compositor's work).
- Extrapolation (not a measurement): frame time ∝ pixels — the rasteriser's cost is per
  fragment — so a headset with two eyes of P pixels takes 2·P·(overhead per pixel + K · cost
  per pixel·light); the table gives that for the XTAL 8K (2 × 3840×2160) and a 2 × 2016×2240
  headset, and the K that fits one 90 Hz frame (11.1 ms).
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_viewport import bench_scene
from common import ROOT, table

from btf_addon.render.settings import RenderSettings
from btf_addon.xr.bridge import BridgeSettings, XRBridge

SIZES = [(64, 48), (128, 96)]
KS = [1, 5, 20]
FRAMES = 4  # timed frames per (size, K), after one warm-up frame
HZ = 90.0
TARGETS = [("XTAL 8K", 3840, 2160), ("2016×2240", 2016, 2240)]
THESIS = "RTX 2080 Ti (thesis): 47–147 FPS at 2 × 3840×2160 with 5 lights"


class PinnedK:
    """Stands in for an eye's FrameBudget: always K lights per frame."""

    def __init__(self, k: int):
        self.k, self.budget_s = k, 1.0

    def frame(self, _drawn: int) -> int:
        return self.k

    def status(self) -> str:
        return f"{self.k} lights/frame"


def build_runtime(out_dir: Path) -> Path:
    spec = importlib.util.spec_from_file_location(
        "btf_xr_runtime_build", ROOT / "tests" / "xr_runtime" / "build.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.build_runtime(out_dir)


def moving_head(frames: int) -> list[list[float]]:
    """A head turning slowly: every frame a new pose, so every eye restarts."""
    return [
        [0.002 * i, 1.6, 0.0, 0.0, math.sin(0.001 * i), 0.0, math.cos(0.001 * i)]
        for i in range(frames)
    ]


def frame_time(scene, work: Path, size: tuple[int, int], k: int) -> float:
    """Mean seconds per submitted stereo frame with K lights per eye."""
    script = work / f"script_{size[0]}_{k}.json"
    script.write_text(
        json.dumps({"eye_size": list(size), "display_period_s": 0.001, "head": moving_head(64)})
    )
    os.environ["BTF_XR_TEST_SCRIPT"] = str(script)
    bridge = XRBridge(scene, RenderSettings(), BridgeSettings(lights_total=4096, show_hud=False))
    bridge.start()
    try:
        for eye in bridge.eyes:
            eye.budget = PinnedK(k)
        while bridge.frames < 1:  # warm-up: session running, programs compiled
            bridge.run_frame()
        bridge.egl.ctx.finish()
        t0, start = time.perf_counter(), bridge.frames
        while bridge.frames < start + FRAMES:
            bridge.run_frame()
        bridge.egl.ctx.finish()
        seconds = (time.perf_counter() - t0) / FRAMES
        bridge.request_stop()
        while bridge.run_frame():
            pass
    finally:
        bridge.close()
    return seconds


def main() -> str:
    scene = bench_scene()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        os.environ["XR_RUNTIME_JSON"] = str(build_runtime(work / "runtime"))
        rows, fits = [], []
        for size in SIZES:
            times = [frame_time(scene, work, size, k) for k in KS]
            pixels = 2 * size[0] * size[1]
            slope, intercept = np.polyfit(KS, times, 1)
            fits.append((intercept / pixels, slope / pixels))
            for k, t in zip(KS, times, strict=True):
                rows.append([f"2 × {size[0]}×{size[1]}", k, t * 1e3, 1.0 / t])
            rows.append(
                [
                    f"2 × {size[0]}×{size[1]} fit",
                    "—",
                    f"{intercept * 1e3:.3g} + {slope * 1e3:.3g}·K",
                    f"{slope / pixels * 1e9:.3g} ns/px·light",
                ]
            )
    out = [table(["eyes", "K", "ms per frame", "FPS"], rows)]
    overhead_pp, cost_ppl = fits[-1]  # the larger size: fixed costs matter least there
    extrapolated = []
    for name, w, h in TARGETS:
        pixels = 2 * w * h
        frame = {k: pixels * (overhead_pp + k * cost_ppl) for k in KS}
        fit_90 = math.floor((1.0 / HZ - pixels * overhead_pp) / (pixels * cost_ppl))
        extrapolated.append(
            [
                f"{name} (2 × {w}×{h})",
                *(f"{frame[k] * 1e3:.4g} ms ({1 / frame[k]:.3g} FPS)" for k in KS),
                max(fit_90, 0),
            ]
        )
    out.append(
        table(
            [
                "llvmpipe, extrapolated ∝ pixels",
                *(f"K = {k}" for k in KS),
                f"K at {HZ:g} Hz",
            ],
            extrapolated,
        )
    )
    out.append(
        f"per pixel: overhead {overhead_pp * 1e9:.3g} ns, {cost_ppl * 1e9:.3g} ns per light "
        f"(fit at 2 × {SIZES[-1][0]}×{SIZES[-1][1]}). {THESIS}."
    )
    return "\n\n".join(out)


if __name__ == "__main__":
    print(main())

"""XTAL bridge (issue 12): the bridge's whole frame loop through the real OpenXR loader and the
OpenXR test runtime (tests/xr_runtime: xrWaitFrame/BeginFrame/LocateViews, per eye
acquire/wait/draw/release, xrEndFrame with its readback of both eyes), on Mesa llvmpipe.

- Cost: submitted frames with a moving head (each eye restarts: World, depth pre-pass, K
  lights, resolve into the sRGB swapchain image) for K = 1, 5, 20 lights per frame pinned, at
  two small eye sizes; mean frame time over a few frames after a warm-up; frame time =
  overhead + cost · K fitted per eye size by least squares, divided by the two eyes' pixels.
  The overhead includes the test runtime's readback of both eyes (a real compositor's work).
  The drawing alone (the bridge's per-eye work, timed inside the loop with the GPU finished)
  is fitted the same way: the rest of the loop is the test runtime's (its readback of both
  eyes, a real compositor's work) and the loader's.
- Extrapolation (not a measurement) of the drawing: fixed + 2·P·(overhead per pixel + K ·
  cost per pixel·light) for two eyes of P pixels — the rasteriser's cost is per fragment;
  the fixed part (vertices, draw calls) and the per-pixel overhead come from the two sizes'
  intercepts — for the XTAL 8K (2 × 3840×2160) and a 2 × 2016×2240 headset, and the K that
  fits one 90 Hz frame (11.1 ms).
- Warm-up (issue 30 item 7): the bridge's own account of its start and first frames
  (``BridgeStatus.warmup``: OpenXR session and GL context, shader compiles, uploads, the
  driver's first draws), per eye size, at K = 1.
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
    """Stands in for the eyes' shared FrameBudget: always K lights per frame."""

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


def frame_time(
    scene, work: Path, size: tuple[int, int], k: int
) -> tuple[float, float, tuple[str, ...]]:
    """Mean seconds per submitted stereo frame with K lights per eye: (the whole frame loop,
    the bridge's drawing alone — both eyes' restart, K lights, resolve, GPU finished), and the
    bridge's warm-up lines (its start and first frames, what they spent: issue 30 item 7)."""
    script = work / f"script_{size[0]}_{k}.json"
    script.write_text(
        json.dumps({"eye_size": list(size), "display_period_s": 0.001, "head": moving_head(64)})
    )
    os.environ["BTF_XR_TEST_SCRIPT"] = str(script)
    # "camera": the head (a real runtime's +y-up pose) starts at the scene camera, looking at
    # the sphere as the viewport benchmark's camera does.
    settings = BridgeSettings(lights_total=4096, show_hud=False, placement="camera")
    bridge = XRBridge(scene, RenderSettings(), settings)
    drawing = [0.0]
    draw_eye = bridge._draw_eye

    def timed_draw_eye(*args):
        t0 = time.perf_counter()
        result = draw_eye(*args)
        bridge.gl.ctx.finish()
        drawing[0] += time.perf_counter() - t0
        return result

    bridge._draw_eye = timed_draw_eye
    bridge.start()
    try:
        bridge.budget.budget = PinnedK(k)  # the eyes' one budget (gl/eye.py SharedBudget)
        for eye in bridge.eyes:
            eye.budget = bridge.budget.budget
        while bridge.frames < 1:  # warm-up: session running, programs compiled
            bridge.run_frame()
        bridge.gl.ctx.finish()
        t0, start, drawing[0] = time.perf_counter(), bridge.frames, 0.0
        while bridge.frames < start + FRAMES:
            bridge.run_frame()
        bridge.gl.ctx.finish()
        seconds = (time.perf_counter() - t0) / FRAMES
        bridge.request_stop()
        while bridge.run_frame():
            pass
    finally:
        bridge.close()
    return seconds, drawing[0] / FRAMES, bridge.status.warmup


def main() -> str:
    scene = bench_scene()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        os.environ["XR_RUNTIME_JSON"] = str(build_runtime(work / "runtime"))
        rows, fits, warmups = [], [], []
        for size in SIZES:
            measured = [frame_time(scene, work, size, k) for k in KS]
            warmups.append(f"2 × {size[0]}×{size[1]}, K = {KS[0]}: " + "; ".join(measured[0][2]))
            pixels = 2 * size[0] * size[1]
            loop = [m[0] for m in measured]
            draw = [m[1] for m in measured]
            slope, intercept = np.polyfit(KS, draw, 1)
            loop_slope, loop_intercept = np.polyfit(KS, loop, 1)
            fits.append((pixels, intercept, slope))
            for k, t, d in zip(KS, loop, draw, strict=True):
                rows.append([f"2 × {size[0]}×{size[1]}", k, t * 1e3, 1.0 / t, d * 1e3])
            rows.append(
                [
                    f"2 × {size[0]}×{size[1]} fit",
                    "—",
                    f"{loop_intercept * 1e3:.3g} + {loop_slope * 1e3:.3g}·K",
                    "",
                    f"{intercept * 1e3:.3g} + {slope * 1e3:.3g}·K "
                    f"({slope / pixels * 1e9:.3g} ns/px·light)",
                ]
            )
    out = [table(["eyes", "K", "ms per frame (loop)", "FPS", "ms drawing (both eyes)"], rows)]
    # The fixed part (vertices: the sphere's 9216 triangles, per-draw calls) and the per-pixel
    # part of the overhead from the two sizes' intercepts; the cost per pixel·light from the
    # larger size (fixed costs matter least there).
    (p1, i1, _), (p2, i2, s2) = fits
    overhead_pp = max((i2 - i1) / (p2 - p1), 0.0)
    fixed = i1 - p1 * overhead_pp
    cost_ppl = s2 / p2
    extrapolated = []
    for name, w, h in TARGETS:
        pixels = 2 * w * h
        frame = {k: fixed + pixels * (overhead_pp + k * cost_ppl) for k in KS}
        fit_90 = math.floor((1.0 / HZ - fixed - pixels * overhead_pp) / (pixels * cost_ppl))
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
                "llvmpipe drawing, extrapolated ∝ pixels",
                *(f"K = {k}" for k in KS),
                f"K at {HZ:g} Hz",
            ],
            extrapolated,
        )
    )
    out.append(
        f"drawing model: {fixed * 1e3:.3g} ms fixed + per pixel {overhead_pp * 1e9:.3g} ns + "
        f"{cost_ppl * 1e9:.3g} ns per light. {THESIS}."
    )
    out.append("warm-up (the bridge's own account, BridgeStatus.warmup):\n" + "\n".join(warmups))
    return "\n\n".join(out)


if __name__ == "__main__":
    print(main())

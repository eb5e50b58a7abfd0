"""VR preview (issue 11): what a stereo frame costs per eye, how many lights per frame fit a
headset's frame budget, and how fast the image converges with the head still.

Standalone moderngl renderer (the viewport's shaders) on Mesa llvmpipe, the scene of
bench_viewport (alu sphere on the wallpaper plane, forest studiolight), seen by the two eyes
of a headset profile (render/headsets.py: OpenXR per-eye projection and view matrices) as two
views of one drawer, exactly as the VR draw callback draws them. Times end with
``ctx.finish()`` (OpenGL queues work; a frame is done when the device is).

- Cost: frames of a moving head (restart + K lights + resolve, per eye) for K = 0, 1, 5, 20 at
  two small eye sizes; best of a few frames; per-eye time = overhead + cost · K fitted by least
  squares, then divided by the eye's pixels.
- Extrapolation (not a measurement): per-eye time ∝ pixels, i.e. a headset eye of P pixels
  takes P · (overhead per pixel + K · cost per pixel·light) — the rasteriser's cost is per
  fragment — and the K that fits 11 ms for both eyes follows.
- FrameBudget with the real clock on the stereo loop, head still (render/frame_budget.py, one
  controller per eye, as the VR callback uses it): the K it settles at and the time until 200
  lights are in; the relative RMSE of the left eye against its 1024-light image on the way.
- Blender's VR session callback as it runs live (issue 35), in bpy: a scene of 200 objects,
  two eyes and a desktop mirror view, per-eye CPU time of ``draw_callback`` at 16×12 pixels
  (the fragment work, BTF decode included, is negligible there: what is left is the overhead
  outside the decode), before and after issue 35's changes in one run. "Before" is the old
  behaviour reproduced on the same code: the plain ``BlenderGPUDevice`` (every uniform
  converted on every draw), the gaze ray-cast on every restart of every eye, and every
  depsgraph update re-exporting the scene; "after" is the live code, its view-transform pass
  included (one more full-screen pass per eye). Head moving 2 mm a frame
  (a tracked head: every frame restarts), with and without a Scene update per frame (our
  exposure, a VR gesture). ``python benchmarks/bench_vr.py --live`` runs only this part.
"""

from __future__ import annotations

import time

import numpy as np
from bench_viewport import bench_scene, rel_rmse
from common import table

from btf_addon.gl.drawer import ProgressiveDrawer, ViewAccumulation
from btf_addon.gl.moderngl_device import ModernGLDevice
from btf_addon.render.frame_budget import FrameBudget
from btf_addon.render.headsets import Eye, profile, stereo_eyes
from btf_addon.scene.scene import look_at

HEAD = look_at((0.0, -4.5, 1.2), (0.0, 0.0, -0.2))  # the viewport benchmark's viewpoint
BUDGET_S = 0.011  # the VR callback's default: one 90 Hz frame
THESIS = "RTX 2080 Ti (thesis): 47–147 FPS at 2 × 3840×2160 with 5 lights"


def camera_vector(eye: Eye) -> np.ndarray:
    return np.array([*eye.position, 1.0], dtype=np.float32)


class Stereo:
    """Two eyes of one drawer: each eye a view with its own lights and progress."""

    def __init__(self, device, drawer, eyes: list[Eye], lights, per_pass: int = 1):
        self.device, self.drawer, self.eyes = device, drawer, eyes
        self.views = []
        for eye in eyes:
            view = ViewAccumulation(device, eye.width, eye.height)
            view.set_lights(lights, per_pass=per_pass)
            self.views.append(view)

    def restart(self, view: ViewAccumulation, eye: Eye) -> None:
        self.drawer.restart(view, eye.clip_from_world, camera_vector(eye))

    def moving_frame(self, k: int) -> None:
        """Both eyes of a frame whose head moved: restart, K lights, resolve."""
        for view, eye in zip(self.views, self.eyes, strict=True):
            self.restart(view, eye)
            if k:
                view.state.per_pass = k
                self.drawer.add_batch(view)
            self.drawer.resolve(view)
        self.device.ctx.finish()

    def release(self) -> None:
        for view in self.views:
            view.release()


def cost_table(device, drawer, lights) -> tuple[str, dict]:
    """Per-eye ms for K = 0, 1, 5, 20 at two sizes and the fitted cost per pixel(·light)."""
    rows, fits = [], {}
    ks = (0, 1, 5, 20)
    for size, factor, reps in (("160×120", 0.5, 3), ("320×240", 1.0, 2)):
        eyes = stereo_eyes(profile("simulated").scaled(factor), HEAD)
        stereo = Stereo(device, drawer, eyes, lights)
        stereo.moving_frame(1)  # first draws at this size: allocation, not timed
        per_eye = []
        for k in ks:
            best = float("inf")
            for _ in range(reps):
                t0 = time.perf_counter()
                stereo.moving_frame(k)
                best = min(best, time.perf_counter() - t0)
            per_eye.append(best / 2)
        stereo.release()
        # K = 0 skips the light pass altogether (restart + resolve only); the lit frames the
        # controller sees are K >= 1, and its model is the line through those
        cost, overhead = np.polyfit(ks[1:], per_eye[1:], 1)
        pixels = eyes[0].width * eyes[0].height
        fits[size] = (pixels, overhead, cost)
        rows.append(
            [
                size,
                *(round(t * 1000, 1) for t in per_eye),
                round(overhead * 1000, 1),
                round(cost * 1000, 2),
                round(cost / pixels * 1e9, 1),
            ]
        )
    headers = [
        "eye size",
        *(f"ms/eye K={k}" for k in ks),
        "fit K≥1: overhead ms",
        "fit K≥1: ms per light",
        "ns per pixel·light",
    ]
    return table(headers, rows), fits


def extrapolation_table(fits: dict) -> str:
    """Headset sizes from the 320×240 fit, everything proportional to pixels (stated)."""
    pixels0, overhead, cost = fits["320×240"]
    o_px, c_px = overhead / pixels0, cost / pixels0
    rows = []
    for name in ("simulated", "generic-2016x2240", "xtal-8k"):
        p = profile(name)
        px = p.eye_width * p.eye_height
        frame = {k: 2 * px * (o_px + c_px * k) for k in (1, 5)}
        k_fit = int(np.floor((BUDGET_S / 2 - px * o_px) / (px * c_px)))
        rows.append(
            [
                f"2 × {p.eye_width}×{p.eye_height} ({name})",
                round(frame[1] * 1000),
                round(frame[5] * 1000),
                k_fit if k_fit >= 1 else "none",
                f"{frame[5] / BUDGET_S:,.0f}×",
            ]
        )
    # the thesis's 47–147 FPS is 21.3–6.8 ms per stereo frame for the XTAL's two 4K eyes
    xtal = profile("xtal-8k")
    xtal_k5 = 2 * xtal.eye_width * xtal.eye_height * (o_px + 5 * c_px)
    slow, fast = (xtal_k5 * fps for fps in (47, 147))
    rows.append([THESIS, "-", "6.8–21.3", "-", f"(it is {slow:,.0f}–{fast:,.0f}× llvmpipe)"])
    headers = [
        "stereo frame (extrapolated from 320×240, llvmpipe)",
        "ms at K=1",
        "ms at K=5",
        "K fitting 11 ms",
        "speed-up needed for K=5 in 11 ms",
    ]
    return table(headers, rows)


def budget_run(
    device, drawer, lights, factor: float, budget_s: float, max_s: float, reference=None
) -> tuple[list, list]:
    """FrameBudget per eye, real clock, head still, until 200 lights are in both eyes or
    ``max_s``. Returns the summary row and, with a ``reference`` (left eye, 1024 lights),
    the error readings after 5, 20, 50 and 200 lights."""
    eyes = stereo_eyes(profile("simulated").scaled(factor), HEAD)
    stereo = Stereo(device, drawer, eyes, lights)
    budgets = [FrameBudget(budget_s) for _ in eyes]
    drawn = [0, 0]
    started = [False, False]
    readings, marks = [], [5, 20, 50, 200]
    ks = []
    t0 = time.perf_counter()
    frames = 0
    while time.perf_counter() - t0 < max_s:
        for i, (view, eye, budget) in enumerate(zip(stereo.views, eyes, budgets, strict=True)):
            k = budget.frame(drawn[i])
            view.state.per_pass = k
            if not started[i]:  # the head is still: one restart, then accumulation only
                stereo.restart(view, eye)
                started[i] = True
            drawn[i] = drawer.add_batch(view)
            drawer.resolve(view)
            device.ctx.finish()
            if i == 0 and max(v.state.done for v in stereo.views) < 200:
                ks.append(k)  # while both eyes still draw (see below)
                status = budget.status()
        frames += 1
        done = [v.state.done for v in stereo.views]
        if reference is not None and marks and done[0] >= marks[0]:
            image = stereo.views[0].read()[..., :3]
            readings.append(
                [done[0], round(time.perf_counter() - t0, 2), round(rel_rmse(image, reference), 4)]
            )
            while marks and done[0] >= marks[0]:
                marks.pop(0)
        if min(done) >= 200:
            break
    elapsed = time.perf_counter() - t0
    reached = min(v.state.done for v in stereo.views)
    if reached >= 200:
        until = round(elapsed, 2)
    else:  # extrapolated: the same frames until all 200 lights are in (stated as such)
        per_light = elapsed / max(reached, 1)
        until = f"≈ {200 * per_light:.0f} (extrapolated from {reached} lights)"
    # K and status of the left eye while both eyes draw: once one eye has all its lights, the
    # other's intervals shrink and its model needs a few frames to tell why (both eyes' work
    # lies in each interval); the last frames of a run do not show the settled state
    settled = int(np.median(ks[len(ks) // 2 :]))
    row = [
        f"2 × {eyes[0].width}×{eyes[0].height}",
        round(budget_s * 1000, 1),
        frames,
        settled,
        status,
        until,
    ]
    stereo.release()
    return row, readings


def reference_image(device, drawer, factor: float) -> np.ndarray:
    """The left eye lit by 1024 lights (another light set: seed 7), as bench_viewport."""
    eye = stereo_eyes(profile("simulated").scaled(factor), HEAD)[0]
    view = ViewAccumulation(device, eye.width, eye.height)
    lights = drawer.scene.environment.virtual_lights(1024, seed=7)
    view.set_lights(lights, per_pass=128)
    drawer.restart(view, eye.clip_from_world, camera_vector(eye))
    while drawer.add_batch(view):
        device.ctx.finish()  # llvmpipe: keep the queue short
    drawer.resolve(view)
    image = view.read()[..., :3]
    view.release()
    return image


def main() -> str:
    scene = bench_scene()
    device = ModernGLDevice()
    drawer = ProgressiveDrawer(device, scene)
    lights = scene.environment.virtual_lights(200)
    out = []
    costs, fits = cost_table(device, drawer, lights)
    out += [costs, extrapolation_table(fits)]
    small = 0.25  # 80×60 per eye: llvmpipe holds the simulated runtime's 20 Hz there
    reference = reference_image(device, drawer, small)
    rows = []
    row, readings = budget_run(device, drawer, lights, 1.0, BUDGET_S, max_s=4.0)
    rows.append(row)
    sim = profile("simulated")
    row, readings = budget_run(
        device, drawer, lights, small, sim.frame_budget_s, max_s=20.0, reference=reference
    )
    rows.append(row)
    out.append(
        table(
            [
                "FrameBudget, head still",
                "budget ms",
                "frames",
                "K settled (left eye)",
                "status (left eye)",
                "s until 200 lights in",
            ],
            rows,
        )
    )
    out.append(
        table(
            [
                f"left eye {int(320 * small)}×{int(240 * small)}: lights in",
                "s since head still",
                "relative RMSE vs 1024",
            ],
            readings,
        )
    )
    drawer.release()
    device.close()
    return "\n\n".join(out)


# ------------------------------------------------------------------ the live session (bpy)
LIVE_OBJECTS = 200
LIVE_FRAMES = 40


def live_scene(bpy):
    """200 small cubes with a plain material on a grid in front of the viewer, a World."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    material = bpy.data.materials.new("Plain")
    mesh = bpy.data.meshes.new("cube")
    import bmesh

    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=0.2)
    bm.to_mesh(mesh)
    bm.free()
    mesh.materials.append(material)
    for i in range(LIVE_OBJECTS):
        obj = bpy.data.objects.new(f"cube{i:03d}", mesh)
        obj.location = ((i % 20) * 0.3 - 3.0, 1.0 + (i // 20) * 0.3, 0.0)
        scene.collection.objects.link(obj)
    scene.world = bpy.data.worlds.new("World")
    vr = scene.btf_vr
    vr.lights_mode, vr.lights_per_frame, vr.lights_total = "FIXED", 1, 64
    vr.show_hud = True
    return scene


class LiveSession:
    """Two eyes and a mirror drawn by ``draw_callback`` as Blender's session draws them."""

    def __init__(self, bpy, xr, legacy: bool) -> None:
        import gpu

        from btf_addon.blender.gpu_draw import BlenderGPUDevice

        self.bpy, self.xr, self.legacy = bpy, xr, legacy
        self.session = type("State", (), {})()
        self.session.navigation_scale = 1.0
        depsgraph = bpy.context.evaluated_depsgraph_get()
        display = None
        if not legacy:  # the live callback draws through the scene's view transform
            from btf_addon.blender.vr.display import DisplayTransform

            display = DisplayTransform()
            display.update(bpy.context.scene)
        self.preview = xr.XRPreview(
            xr.SceneSource(lambda: depsgraph, lambda: self.session), display=display
        )
        if legacy:
            self.preview.device = BlenderGPUDevice()
        self.in_draw_calls = [0.0]  # seconds inside GPUBatch.draw (the GPU's work, the decode)
        device, draw = self.preview.device, type(self.preview.device).draw

        def timed_draw(program, vertices, uniforms, samplers):
            return draw(
                device, program, _TimedBatch(vertices, self.in_draw_calls), uniforms, samplers
            )

        device.draw = timed_draw
        self.sim = profile("simulated").scaled(0.05)  # 16×12 per eye
        self.offscreens = {
            key: gpu.types.GPUOffScreen(w, h, format="RGBA16F")
            for key, (w, h) in (("eye", (16, 12)), ("mirror", (32, 24)))
        }
        self.times = {"left": [], "right": [], "mirror": []}
        self.outside = {"left": [], "right": [], "mirror": []}  # less the GPUBatch.draw time

    def frame(self, step: int, scene_update: bool) -> None:
        head = (0.002 * step, -4.0, 1.0)
        world_from_head = look_at(head, (0.0, 2.0, 0.0))
        self.session.viewer_pose_location = head
        if scene_update:  # one depsgraph update of the Scene itself (exposure, a gesture)
            if self.legacy:
                self.preview.invalidate()  # the old handler: every update re-exported
            else:
                scene = self.bpy.context.scene
                self.preview.depsgraph_updated(_Updates(scene))
        left, right = stereo_eyes(self.sim, world_from_head)
        for key, eye in (("left", left), ("right", right)):  # the headset first, as Blender
            if self.legacy:
                self.preview.gaze = None  # the old callback cast the gaze on every restart
            self._draw(key, self.offscreens["eye"], eye.clip_from_view, eye.view_from_world)
        mirror = (_symmetric_projection(32 / 24), np.linalg.inv(world_from_head))
        self._draw("mirror", self.offscreens["mirror"], *mirror)

    def _draw(self, key, offscreen, clip_from_view, view_from_world) -> None:
        import gpu
        import mathutils

        with offscreen.bind(), gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
            gpu.matrix.load_projection_matrix(mathutils.Matrix(clip_from_view.tolist()))
            gpu.matrix.load_matrix(mathutils.Matrix(view_from_world.tolist()))
            t0, gpu0 = time.perf_counter(), self.in_draw_calls[0]
            self.xr.draw_callback(self.preview)
            elapsed = time.perf_counter() - t0
            self.times[key].append(elapsed)
            self.outside[key].append(elapsed - (self.in_draw_calls[0] - gpu0))
        if self.preview.error:
            raise RuntimeError(self.preview.error)

    def release(self) -> None:
        self.preview.release()
        for offscreen in self.offscreens.values():
            offscreen.free()


class _TimedBatch:
    """A GPUBatch whose ``draw`` adds its wall time to ``total[0]``."""

    def __init__(self, batch, total: list) -> None:
        self.batch, self.total = batch, total

    def draw(self, program) -> None:
        t0 = time.perf_counter()
        self.batch.draw(program)
        self.total[0] += time.perf_counter() - t0


class _Updates:
    """A depsgraph's ``updates`` holding one update of ``datablock`` (no geometry, shading)."""

    def __init__(self, datablock) -> None:
        update = type("Update", (), {})()
        update.id, update.is_updated_geometry, update.is_updated_shading = datablock, False, False
        self.updates = [update]


def _symmetric_projection(aspect: float, near: float = 0.1, far: float = 100.0) -> np.ndarray:
    t = 0.5
    return np.array(
        [
            [1 / (aspect * t), 0, 0, 0],
            [0, 1 / t, 0, 0],
            [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
            [0, 0, -1, 0],
        ]
    )


def live_session_table() -> str:
    """Per-eye callback ms before/after (module docstring), as medians over the frames after
    the first two (export and GPU allocation)."""
    try:
        import bpy
    except ImportError:
        return "live session: skipped (no bpy)"
    from blender_helpers import init_gpu_module

    import btf_addon

    btf_addon.register()
    try:
        from btf_addon.blender.vr import preview as xr

        live_scene(bpy)
        init_gpu_module(bpy)
        rows = []
        for scene_update in (False, True):
            # Before and after interleaved frame by frame: a shared machine's load drifts.
            sessions = {legacy: LiveSession(bpy, xr, legacy) for legacy in (True, False)}
            try:
                for step in range(LIVE_FRAMES):
                    for session in sessions.values():
                        session.frame(step, scene_update)
                medians = {
                    legacy: {k: float(np.median(t[2:])) for k, t in session.times.items()}
                    for legacy, session in sessions.items()
                }
                outside = {
                    legacy: {k: float(np.median(t[2:])) for k, t in session.outside.items()}
                    for legacy, session in sessions.items()
                }
                casts = {legacy: s.preview.ray_casts for legacy, s in sessions.items()}
                conversions = sessions[False].preview.device.conversions
            finally:
                for session in sessions.values():
                    session.release()
            before, after = medians[True], medians[False]
            eye_before = (before["left"] + before["right"]) / 2
            eye_after = (after["left"] + after["right"]) / 2
            out_before = (outside[True]["left"] + outside[True]["right"]) / 2
            out_after = (outside[False]["left"] + outside[False]["right"]) / 2
            rows.append(
                [
                    "Scene update every frame" if scene_update else "no depsgraph update",
                    round(eye_before * 1000, 2),
                    round(eye_after * 1000, 2),
                    round(eye_before / eye_after, 2),
                    round(out_before * 1000, 2),
                    round(out_after * 1000, 2),
                    round(out_before / out_after, 2),
                    round(before["mirror"] * 1000, 2),
                    round(after["mirror"] * 1000, 2),
                    f"{casts[True]} → {casts[False]}",
                    conversions,
                ]
            )
    finally:
        btf_addon.unregister()
    return table(
        [
            f"{LIVE_OBJECTS} objects, 2 eyes 16×12 + mirror 32×24, head moving",
            "ms/eye before",
            "ms/eye after",
            "before ÷ after",
            "ms/eye outside draw calls, before",
            "after",
            "before ÷ after",
            "mirror ms before",
            "mirror ms after",
            f"gaze casts before → after ({LIVE_FRAMES} frames)",
            "uniform conversions after",
        ],
        rows,
    )


if __name__ == "__main__":
    import sys

    t_start = time.perf_counter()
    if "--live" not in sys.argv:
        print(main())
    print(live_session_table())
    print(f"\n(bench_vr took {time.perf_counter() - t_start:.0f} s)")

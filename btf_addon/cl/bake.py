"""The light bake on the final render's device: F12's paths at bake points, and a frame lit by
a bake (what the drawer plays back), both through the renderer's own program
(kernels/render_direct.cl ``bake_light``, ``render_baked``; the path itself is
kernels/include/btf_path.h, the one F12 traces).

A bake point's value per view bin is the light leaving its footprint towards that view divided,
per channel, by the material's response there to one light along the normal
(docs/accuracy.md "The light bake"): playback multiplies it by the response at the pixel's own
texel, so the bake carries the light and the live decode the material's detail.

Work goes in passes of a few samples over every point, each pass in launches of a bounded
number of points: a cancel between launches keeps every finished pass, so a stopped bake is a
noisier bake of the whole scene, never a bake of half of it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from ..core import memory
from ..render.light_bake import GRID_ARRAYS, LightBake, MeshBake, mesh_digests, scene_digest
from ..render.pixel_filter import r2_points
from ..scene.bake_analysis import bake_needs
from ..scene.bake_points import BakeGrid, bin_directions, build_grid
from .kernel_args import ArgumentKernel
from .renderer import LOCAL_SIZE, CLRenderer

#: Samples per point and bin in one pass: a cancel loses at most one pass.
PASS_SAMPLES = 16
#: A launch's target length, as the final render's (render/launch.py): progress and cancel
#: stay responsive whatever a point costs.
LAUNCH_SECONDS = 0.1
#: Host bytes per baked value (a point × a view bin): the float32 ratio and the float64 sums
#: of light and response with a pass's own copies (4 × 4 × 8). With the grid's own bytes, what
#: a bake is refused by up front (core/memory.py) before any device work.
BAKE_VALUE_BYTES = 12 + 128
#: Below this response (per channel) a texel gives no light to scale: its ratio is 0 there.
RESPONSE_FLOOR = 1e-8


@dataclass
class BakedLight:
    """(P, V², 3) float32 ``ratio``: light per unit response per point and view bin;
    ``samples``: the samples each value averages (the last finished pass's count)."""

    ratio: np.ndarray
    view_bins: int
    samples: int
    seconds: float

    @property
    def nbytes(self) -> int:
        return int(self.ratio.nbytes)


def _device_order(renderer: CLRenderer, triangles: np.ndarray) -> np.ndarray:
    """Global triangle indices (the scene's meshes in order) → the renderer's (BVH order)."""
    inverse = np.empty(len(renderer.triangle_order), np.int64)
    inverse[renderer.triangle_order] = np.arange(len(renderer.triangle_order))
    out = np.full(triangles.shape, -1, np.int64)
    ok = (triangles >= 0) & (triangles < len(inverse))
    out[ok] = inverse[triangles[ok]]
    return out.astype(np.int32)


def bake_light(
    renderer: CLRenderer,
    footprint_tri: np.ndarray,
    footprint_bary: np.ndarray,
    view_bins: int,
    samples: int,
    max_bounces: int,
    seed: int = 0,
    progress: Callable[[float], bool] | None = None,
) -> BakedLight:
    """Bake ``samples`` paths per point and view bin (rounded up to whole passes) at the points
    whose footprints are given (scene/bake_points.py: (P, F) triangles in the scene's order and
    (P, F, 2) barycentrics). ``progress``
    sees the fraction done after each launch; False stops after the last finished pass."""
    cl, ctx = renderer.cl, renderer.ctx
    t0 = time.perf_counter()
    renderer.prepare_sampled()  # the Sampled mode's tables, as F12 packs them
    points, bins = len(footprint_tri), view_bins * view_bins
    footprint = footprint_tri.shape[1] if points else 1
    bounces = max(max_bounces, 0) if renderer.features.shadows else 0
    buf = renderer._buffer
    foot_tri = buf(_device_order(renderer, footprint_tri).ravel(), np.int32)
    foot_bary = buf(footprint_bary.ravel(), np.float32)
    dirs = np.zeros((bins, 4), np.float32)
    dirs[:, :3] = bin_directions(view_bins)
    bin_dirs = buf(dirs.ravel(), np.float32)
    world = [renderer.eps, *renderer._env_args(), *renderer._next_event_tables()]
    passes = max(1, -(-int(samples) // PASS_SAMPLES))
    radiance = np.zeros((points, bins, 4), np.float64)
    response = np.zeros((points, bins, 4), np.float64)
    kernel = ArgumentKernel(cl.Kernel(renderer.program, "bake_light"))
    chunk = 64  # points per launch; grows or shrinks to LAUNCH_SECONDS
    done, total = 0, passes * max(points, 1)
    mf = cl.mem_flags
    finished = 0
    for p in range(passes):
        pass_radiance, pass_response = np.zeros_like(radiance), np.zeros_like(response)
        start = 0
        while start < points:
            count = min(chunk, points - start)
            out_l = cl.Buffer(ctx.context, mf.WRITE_ONLY, count * bins * 16)
            out_r = cl.Buffer(ctx.context, mf.WRITE_ONLY, count * bins * 16)
            tl = time.perf_counter()
            kernel(
                ctx.queue,
                (-(-count // LOCAL_SIZE[0]) * LOCAL_SIZE[0], bins),
                (LOCAL_SIZE[0], 1),
                np.int32(start),
                np.int32(start + count),  # the launch's last point + 1: its buffers' end
                np.int32(bins),
                np.int32(footprint),
                foot_tri,
                foot_bary,
                bin_dirs,
                *renderer._scene_args(),
                *world,
                np.int32(p * PASS_SAMPLES),
                np.int32(PASS_SAMPLES),
                np.uint32(seed),
                np.int32(bounces),
                np.float32(max(renderer.clamp_indirect, 0.0)),
                out_l,
                out_r,
            )
            for device, host in ((out_l, pass_radiance), (out_r, pass_response)):
                part = np.empty((count, bins, 4), np.float32)
                cl.enqueue_copy(ctx.queue, part, device)
                host[start : start + count] = part
            seconds = time.perf_counter() - tl
            chunk = int(np.clip(chunk * LAUNCH_SECONDS / max(seconds, 1e-4), 16, 1 << 16))
            start += count
            done += count
            if start >= points:  # the pass is whole: kept whatever the answer below
                radiance += pass_radiance
                response += pass_response
                finished += 1
            if progress is not None and not progress(done / total):
                return _finish(radiance, response, view_bins, finished, t0)
    return _finish(radiance, response, view_bins, finished, t0)


def _finish(radiance, response, view_bins, passes, t0) -> BakedLight:
    unit = response[..., :3]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(unit > RESPONSE_FLOOR, radiance[..., :3] / unit, 0.0)
    ratio = np.nan_to_num(ratio, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
    return BakedLight(ratio, view_bins, passes * PASS_SAMPLES, time.perf_counter() - t0)


def render_baked(
    renderer: CLRenderer,
    grid: BakeGrid,
    baked: BakedLight,
    aa_samples: int = 16,
    times_response: bool = True,
) -> np.ndarray:
    """(h, w, 4) the renderer's camera view lit by ``baked``: what the drawer shows, with the
    film's subpixels (``aa_samples`` R2 points through the film filter, rotated per pixel;
    1: pixel centres). ``times_response`` False: the interpolated values alone."""
    cl, ctx = renderer.cl, renderer.ctx
    w, h = renderer.width, renderer.height
    buf = renderer._buffer
    order = renderer.triangle_order
    values = np.zeros((max(grid.point_count, 1), baked.view_bins**2, 4), np.float32)
    values[: grid.point_count, :, :3] = baked.ratio
    aa = max(int(aa_samples), 1) if renderer.film is not None else 1
    kernel = cl.Kernel(renderer.program, "render_baked")
    out = cl.Buffer(ctx.context, cl.mem_flags.WRITE_ONLY, w * h * 16)
    env = renderer.scene.environment
    kernel(
        ctx.queue,
        renderer._global_size(h),
        LOCAL_SIZE,
        np.int32(w),
        np.int32(h),
        np.int32(0),
        renderer._world_from_clip(),
        *renderer._scene_args(),
        renderer.eps,
        renderer.env,
        np.int32(env.width),
        np.int32(env.height),
        np.array([env.rotation_z_rad, 1.0], dtype=np.float32),
        buf(grid.tri_cuts[order], np.int32),
        buf(grid.tri_first[order], np.int32),
        buf(grid.tri_points, np.int32),
        buf(values.ravel(), np.float32),
        np.int32(baked.view_bins),
        buf(r2_points(aa).ravel(), np.float32),
        np.int32(aa),
        renderer.filter_table,
        np.int32(renderer.transparent),
        np.int32(times_response),
        out,
    )
    image = np.empty((h, w, 4), np.float32)
    cl.enqueue_copy(ctx.queue, image, out)
    return image


@dataclass(frozen=True)
class BakeKnobs:
    """The bake's quality knobs (docs/accuracy.md "The light bake" measures each): bake points
    ``spacing`` apart (scene units), ``view_bins`` × ``view_bins`` view directions, ``samples``
    paths per point and bin, ``footprint`` surface positions per point; ``bounces`` and
    ``clamp_indirect`` as F12's Sampled mode (render/settings.py)."""

    spacing: float = 0.05
    view_bins: int = 5
    samples: int = 64
    footprint: int = 16
    bounces: int = 4
    clamp_indirect: float = 10.0
    seed: int = 0


def bake_scene(
    scene,
    cl_context,
    knobs: BakeKnobs = BakeKnobs(),
    progress: Callable[[float], bool] | None = None,
) -> LightBake:
    """The scene analysed (scene/bake_analysis.py), and the meshes that need it baked on one
    renderer of the scene; the others are listed with the reason they were skipped."""
    t0 = time.perf_counter()
    needs = bake_needs(scene)
    corners = [m.world_space_corners() for m in scene.meshes]
    grid = build_grid(corners, knobs.spacing, footprint=knobs.footprint, seed=knobs.seed)
    wanted = np.array([n.anything for n in needs], bool)
    chosen = np.flatnonzero(wanted[grid.point_mesh]) if grid.point_count else np.zeros(0, int)
    bins = knobs.view_bins**2
    memory.require(
        memory.Estimate(
            f"a light bake of {len(chosen)} points × {bins} view directions",
            len(chosen) * bins * BAKE_VALUE_BYTES + grid.nbytes,
            "raise the spacing or lower the view directions",
        )
    )
    ratio = np.zeros((grid.point_count, bins, 3), np.float32)
    samples = 0
    if len(chosen):
        renderer = CLRenderer(scene, 1, 1, cl_context, film=None)
        renderer.clamp_indirect = knobs.clamp_indirect
        baked = bake_light(
            renderer,
            grid.footprint_tri[chosen],
            grid.footprint_bary[chosen],
            knobs.view_bins,
            knobs.samples,
            knobs.bounces,
            knobs.seed,
            progress,
        )
        ratio[chosen] = baked.ratio
        samples = baked.samples
    seconds = time.perf_counter() - t0
    digests = mesh_digests(scene)
    counts = np.bincount(grid.point_mesh, minlength=len(scene.meshes)) if grid.point_count else None
    total_points = max(len(chosen), 1)
    meshes = []
    for i, need in enumerate(needs):
        points = int(counts[i]) if counts is not None and need.anything else 0
        meshes.append(
            MeshBake(
                name=need.name,
                digest=digests[need.name],
                baked=need.anything,
                shadows=need.shadows,
                interreflection=need.interreflection,
                reason=need.reason,
                neighbours=list(need.neighbours),
                points=points,
                # the bake's time shared by points: every point costs about the same
                seconds=round(seconds * points / total_points, 3),
            )
        )
    arrays = {k: getattr(grid, k) for k in GRID_ARRAYS}
    arrays["ratio"] = ratio
    knob_values = {**asdict(knobs), "samples": samples}
    return LightBake(arrays, knob_values, meshes, scene_digest(scene), seconds)

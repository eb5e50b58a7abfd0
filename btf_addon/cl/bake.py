"""The light bake on the final render's device: F12's paths at bake points, and a frame lit by
a bake (what the drawer plays back), both through the renderer's own program
(kernels/render_direct.cl ``bake_light``, ``render_baked``; the path itself is
kernels/include/btf_path.h, the one F12 traces).

A bake point's value per view bin is the light leaving its footprint towards that view divided,
per channel, by the material's response there to one light from the point's light direction
(docs/accuracy.md "The light bake"): playback multiplies it by the response at the pixel's own
texel, so the bake carries the light and the live decode the material's detail. The light
direction is traced first (``light_directions``): the mean direction, weighted by irradiance,
of the World's and Blender's light that reaches the footprint. An analytic
material's value is divided instead by its unshadowed light (the same paths with nothing in
the way, ``CLRenderer.open_bvh``): what the bins carry is then shadows and interreflection,
and playback multiplies them by the unshadowed light computed per pixel
(kernels/include/btf_lobe.h), so a glossy lobe follows the view exactly (docs/accuracy.md "The
light bake played back").

Work goes in passes of a few samples over every point, each pass in launches of a bounded
number of points: a cancel between launches keeps every finished pass, so a stopped bake is a
noisier bake of the whole scene, never a bake of half of it.

A point's paths are seeded by its index in the whole grid, never by its place in the launched
subset, so a point's values do not depend on which other points are baked with it: a re-bake
that traces only the stale meshes (``bake_scene``'s ``previous``) gives them, bit for bit, what
a full bake of the same scene gives them.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from ..core import memory
from ..core.sampling.world_pyramid import LOBE_SAMPLES
from ..render.light_bake import GRID_ARRAYS, LightBake, MeshBake, mesh_digest, scene_digest
from ..render.pixel_filter import r2_points
from ..scene.bake_analysis import bake_needs, neighbours_by_name
from ..scene.bake_points import BakeGrid, bin_directions, build_grid, pack_values
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
#: Host bytes per point beside its values: its light direction (float32, and float32 for
#: the device's copy with a pad) and the direction's sums (4 × float32).
BAKE_POINT_BYTES = 12 + 16 + 16
#: Below this response (per channel) a texel gives no light to scale: its ratio is 0 there.
RESPONSE_FLOOR = 1e-8
#: Draws per point for its light direction (one of the World and one per Blender light each):
#: a mean direction, so a few hundred settle it to about a degree under an even sky.
DIRECTION_SAMPLES = 256
#: The light direction's lowest elevation: cos 75°, where measured BTFs end (DESIGN.md:
#: nothing is measured past θ = 75°); a response to lower light is extrapolated.
MIN_LIGHT_COS = float(np.cos(np.radians(75.0)))


@dataclass
class BakedLight:
    """(P, V², 3) float32 ``ratio``: light per unit response per point and view bin;
    (P, 3) float32 ``light_dir``: the unit direction the response is to, per point (its frame;
    None: the normal); ``samples``: the samples each value averages (the last finished pass's
    count)."""

    ratio: np.ndarray
    view_bins: int
    samples: int
    seconds: float
    light_dir: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.light_dir is None:
            self.light_dir = np.tile(np.float32([0.0, 0.0, 1.0]), (len(self.ratio), 1))

    @property
    def nbytes(self) -> int:
        return int(self.ratio.nbytes + self.light_dir.nbytes)


def unit_light_directions(sums: np.ndarray) -> np.ndarray:
    """(P, 4) ``bake_light_direction`` sums (Σ E·wi, Σ E) → (P, 3) float32 unit directions:
    their mean direction raised to MIN_LIGHT_COS at least; the normal where no light arrived
    or the mean is shorter than 1e-3 of it (light from all round: no direction stands out)."""
    sums = np.nan_to_num(np.asarray(sums, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    towards, total = sums[:, :3], sums[:, 3]
    length = np.linalg.norm(towards, axis=1)
    ok = (total > 0.0) & (length > 1e-3 * np.maximum(total, 0.0))
    d = np.where(ok[:, None], towards / np.where(ok, length, 1.0)[:, None], (0.0, 0.0, 1.0))
    # raised towards the normal along its own azimuth to MIN_LIGHT_COS
    low = d[:, 2] < MIN_LIGHT_COS
    side = np.hypot(d[:, 0], d[:, 1])
    scale = np.sqrt(1.0 - MIN_LIGHT_COS**2) / np.where(side > 0.0, side, 1.0)
    d[low, :2] *= scale[low, None]
    d[low, 2] = MIN_LIGHT_COS
    return d.astype(np.float32)


def light_directions(
    renderer: CLRenderer,
    foot_tri,
    foot_bary,
    ids,
    points: int,
    footprint: int,
    seed: int,
    progress: Callable[[float], bool] | None = None,
) -> np.ndarray | None:
    """(points, 3) float32 unit light directions (``unit_light_directions``) from
    DIRECTION_SAMPLES draws per point (kernels/render_direct.cl ``bake_light_direction``);
    the footprints and ids as ``bake_light`` uploaded them. One launch per 4096 points (a
    point costs a few hundred shadow rays: a few percent of its bake), each followed by
    ``progress(0.0)``; None where it answers False (cancelled)."""
    cl, ctx = renderer.cl, renderer.ctx
    tables = renderer.plain_env_tables()
    kernel = ArgumentKernel(cl.Kernel(renderer.program, "bake_light_direction"))
    sums = np.zeros((points, 4), np.float32)
    step = 4096
    for start in range(0, points, step):
        count = min(step, points - start)
        out = cl.Buffer(ctx.context, cl.mem_flags.WRITE_ONLY, count * 16)
        kernel(
            ctx.queue,
            (-(-count // LOCAL_SIZE[0]) * LOCAL_SIZE[0],),
            (LOCAL_SIZE[0],),
            np.int32(start),
            np.int32(start + count),
            np.int32(footprint),
            foot_tri,
            foot_bary,
            ids,
            *renderer._scene_args(),
            renderer.eps,
            *renderer._env_args(),
            *tables,
            np.int32(DIRECTION_SAMPLES),
            np.uint32(seed),
            out,
        )
        cl.enqueue_copy(ctx.queue, sums[start : start + count], out)
        if progress is not None and not progress(0.0):
            return None
    return unit_light_directions(sums)


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
    point_ids: np.ndarray | None = None,
) -> BakedLight:
    """Bake ``samples`` paths per point and view bin (rounded up to whole passes) at the points
    whose footprints are given (scene/bake_points.py: (P, F) triangles in the scene's order and
    (P, F, 2) barycentrics). ``point_ids``: each footprint's point in the whole grid, what its
    paths are seeded by (None: 0 … P − 1, the footprints are the whole grid). ``progress``
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
    ids = np.arange(points) if point_ids is None else np.asarray(point_ids)
    if ids.shape != (points,):
        raise ValueError(f"point_ids must be ({points},), not {ids.shape}")
    ids = buf(ids, np.int32)
    dirs = np.zeros((bins, 4), np.float32)
    dirs[:, :3] = bin_directions(view_bins)
    bin_dirs = buf(dirs.ravel(), np.float32)
    world = [renderer.eps, *renderer._env_args(), *renderer._next_event_tables()]
    passes = whole_passes(samples) // PASS_SAMPLES
    radiance = np.zeros((points, bins, 4), np.float64)
    response = np.zeros((points, bins, 4), np.float64)
    light_dir = light_directions(
        renderer, foot_tri, foot_bary, ids, points, footprint, seed, progress
    )
    if light_dir is None:  # cancelled before any pass: nothing baked
        return _finish(radiance, response, None, view_bins, 0, t0)
    dir_buf = buf(np.column_stack([light_dir, np.zeros(points)]).ravel(), np.float32)
    kernel = ArgumentKernel(cl.Kernel(renderer.program, "bake_light"))
    open_bvh = renderer.open_bvh()
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
                ids,
                bin_dirs,
                *renderer._scene_args(),
                *world,
                np.int32(p * PASS_SAMPLES),
                np.int32(PASS_SAMPLES),
                np.uint32(seed),
                np.int32(bounces),
                np.float32(max(renderer.clamp_indirect, 0.0)),
                *open_bvh,
                dir_buf,
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
                return _finish(radiance, response, light_dir, view_bins, finished, t0)
    return _finish(radiance, response, light_dir, view_bins, finished, t0)


def _finish(radiance, response, light_dir, view_bins, passes, t0) -> BakedLight:
    unit = response[..., :3]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(unit > RESPONSE_FLOOR, radiance[..., :3] / unit, 0.0)
    ratio = np.nan_to_num(ratio, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
    seconds = time.perf_counter() - t0
    return BakedLight(ratio, view_bins, passes * PASS_SAMPLES, seconds, light_dir)


def render_baked(
    renderer: CLRenderer,
    grid: BakeGrid,
    baked: BakedLight,
    aa_samples: int = 16,
    times_response: bool = True,
    lobe_samples: int = LOBE_SAMPLES,
) -> np.ndarray:
    """(h, w, 4) the renderer's camera view lit by ``baked``: what the drawer shows, with the
    film's subpixels (``aa_samples`` R2 points through the film filter, rotated per pixel;
    1: pixel centres; subpixel s reads an analytic object's unshadowed light with the drawer's
    frame s directions, ``lobe_samples`` of them). ``times_response`` False: the interpolated
    values alone."""
    cl, ctx = renderer.cl, renderer.ctx
    w, h = renderer.width, renderer.height
    buf = renderer._buffer
    order = renderer.triangle_order
    values = pack_values(baked.ratio, baked.light_dir)
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
        *renderer.lobe_args(),
        np.int32(max(int(lobe_samples), 1)),
        out,
    )
    image = np.empty((h, w, 4), np.float32)
    cl.enqueue_copy(ctx.queue, image, out)
    return image


def playback_grid(bake: LightBake) -> BakeGrid:
    """A bake's grid as ``render_baked`` reads it (the footprints, which only a bake reads,
    do not travel with the file: one sample at corner 0 stands in)."""
    a, points = bake.arrays, len(bake.arrays["positions"])
    return BakeGrid(
        spacing=float(bake.knobs.get("spacing", 0.0)),
        footprint_tri=np.zeros((points, 1), np.int32),
        footprint_bary=np.zeros((points, 1, 2), np.float32),
        **{k: a[k] for k in GRID_ARRAYS},
    )


def baked_light(bake: LightBake) -> BakedLight:
    """A bake's values as ``render_baked`` takes them."""
    samples = int(bake.knobs.get("samples", 0))
    a = bake.arrays
    return BakedLight(a["ratio"], bake.view_bins, samples, bake.seconds, a["light_dir"])


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


def whole_passes(samples: int) -> int:
    """The samples a finished bake asked for ``samples`` averages: whole passes of
    PASS_SAMPLES, one at least (what ``bake_light`` traces and a finished bake's knobs say)."""
    return max(1, -(-int(samples) // PASS_SAMPLES)) * PASS_SAMPLES


def mesh_blocks(point_mesh: np.ndarray, meshes: int) -> np.ndarray | None:
    """(meshes + 1,) each mesh's first point, then the point count: mesh m owns points
    [a[m], a[m + 1]). None where its points are not one block per mesh in the meshes' order.
    scene/bake_points.py ``build_grid`` numbers points by their first grid vertex, vertices go
    triangle by triangle and mesh by mesh, and welding joins vertices of one mesh only: a
    grid's points are always such blocks (``bake_scene`` asserts it)."""
    point_mesh = np.asarray(point_mesh)
    if len(point_mesh) and (
        np.any(np.diff(point_mesh) < 0) or point_mesh[0] < 0 or point_mesh[-1] >= meshes
    ):
        return None
    counts = np.bincount(point_mesh, minlength=meshes) if len(point_mesh) else np.zeros(meshes)
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


@dataclass
class _Reuse:
    """What a re-bake takes from the last bake: per mesh (index in the scene now) the first
    point of its block there (``kept``), or why it is traced again (``why``)."""

    kept: dict[int, int]
    why: dict[int, str]


def _knobs_differ(last: dict, knobs: BakeKnobs) -> str:
    """The knobs a bake's ``last`` differ in from a finished bake with ``knobs``, as
    "name then → now"; empty where none does (a cancelled bake differs in its samples)."""
    now = {**asdict(knobs), "samples": whole_passes(knobs.samples)}
    names = [k for k in dict.fromkeys([*now, *last]) if last.get(k) != now.get(k)]
    return ", ".join(f"{k} {last.get(k)} → {now.get(k)}" for k in names)


def _reuse(
    previous: LightBake | None,
    knobs: BakeKnobs,
    needs: list,
    digests: dict[str, str],
    digest_of_scene: str,
    blocks: np.ndarray,
) -> _Reuse:
    """Which meshes that need a bake keep their values from ``previous`` (``bake_scene``'s
    rule) and why the others do not."""
    out = _Reuse({}, {})
    if previous is None:
        return out
    wanted = [need for need in needs if need.anything]
    differ = _knobs_differ(previous.knobs, knobs)
    old = mesh_blocks(previous.arrays["point_mesh"], len(previous.meshes))
    everything = (
        f"the last bake's knobs differ ({differ})"
        if differ
        else "the last bake's points are not in blocks per mesh"
        if old is None
        else ""
    )
    if everything:
        out.why = {need.mesh: everything for need in wanted}
        return out
    stale = previous.why_stale(digests, digest_of_scene, neighbours=neighbours_by_name(needs))
    index = {m.name: k for k, m in enumerate(previous.meshes)}
    for need in wanted:
        k = index.get(need.name)
        if k is None:
            out.why[need.mesh] = "new since the last bake"
        elif not previous.meshes[k].baked:
            out.why[need.mesh] = "not baked last time"
        elif need.name in stale:
            out.why[need.mesh] = stale[need.name]
        elif old[k + 1] - old[k] != blocks[need.mesh + 1] - blocks[need.mesh]:
            out.why[need.mesh] = "its bake points differ from the last bake's"
        else:
            out.kept[need.mesh] = int(old[k])
    return out


def bake_scene(
    scene,
    cl_context,
    knobs: BakeKnobs = BakeKnobs(),
    progress: Callable[[float], bool] | None = None,
    previous: LightBake | None = None,
) -> LightBake:
    """The scene analysed (scene/bake_analysis.py), and the meshes that need it baked on one
    renderer of the scene; the others are listed with the reason they were skipped.

    ``previous``: the last bake of this scene (render/light_bake.py ``load``), None for a bake
    of everything. A mesh that needs a bake keeps its values from there, copied, not traced,
    when the last bake was made with the same knobs (its samples: whole passes of ours, so a
    cancelled bake is baked again whole), baked it, does not find it stale
    (``LightBake.stale`` with the current analysis' neighbours) and has as many points there
    as the grid gives it now. Only the others go to the device; their MeshBake says why
    (``rebaked``), a kept one says ``kept``. A mesh that needs no bake now is not baked,
    whether the last bake had it or not (its values there are not carried over).

    ``cl_context``: the OpenCL context, or a function that makes one, called only when
    something is traced: a re-bake with nothing stale opens no device (a machine without a
    working OpenCL driver can still re-save an unchanged bake)."""
    t0 = time.perf_counter()
    needs = bake_needs(scene)
    corners = [m.world_space_corners() for m in scene.meshes]
    grid = build_grid(corners, knobs.spacing, footprint=knobs.footprint, seed=knobs.seed)
    blocks = mesh_blocks(grid.point_mesh, len(scene.meshes))
    assert blocks is not None, "a bake grid's points must be one block per mesh, in order"
    digests = {n.name: mesh_digest(scene, scene.meshes[n.mesh], corners[n.mesh]) for n in needs}
    reuse = _reuse(previous, knobs, needs, digests, scene_digest(scene), blocks)
    traced = [need.anything and need.mesh not in reuse.kept for need in needs]
    chosen = np.flatnonzero(np.repeat(traced, np.diff(blocks)))
    kept_points = sum(int(blocks[i + 1] - blocks[i]) for i in reuse.kept)
    bins = knobs.view_bins**2
    memory.require(
        memory.Estimate(
            f"a light bake of {len(chosen)} points × {bins} view directions",
            (len(chosen) * BAKE_VALUE_BYTES + kept_points * 12) * bins
            + grid.point_count * BAKE_POINT_BYTES
            + grid.nbytes,
            "raise the spacing or lower the view directions",
        )
    )
    ratio = np.zeros((grid.point_count, bins, 3), np.float32)
    light_dir = np.tile(np.float32([0.0, 0.0, 1.0]), (grid.point_count, 1))
    for i, first in reuse.kept.items():
        count = blocks[i + 1] - blocks[i]
        for name, array in (("ratio", ratio), ("light_dir", light_dir)):
            array[blocks[i] : blocks[i + 1]] = previous.arrays[name][first : first + count]
    # What every baked value averages: the kept ones a finished bake's samples (the knobs
    # matched), the traced ones what the device finished; fewer (a cancel) and the next
    # re-bake finds the knobs differ and bakes everything again.
    samples = int(previous.knobs["samples"]) if reuse.kept else 0
    if len(chosen):
        context = cl_context() if callable(cl_context) else cl_context
        renderer = CLRenderer(scene, 1, 1, context, film=None)
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
            point_ids=chosen,
        )
        ratio[chosen] = baked.ratio
        light_dir[chosen] = baked.light_dir
        samples = baked.samples
    seconds = time.perf_counter() - t0
    meshes = [
        _mesh_bake(need, digests[need.name], blocks, reuse, seconds / max(len(chosen), 1))
        for need in needs
    ]
    arrays = {k: getattr(grid, k) for k in GRID_ARRAYS}
    arrays["ratio"] = ratio
    arrays["light_dir"] = light_dir
    knob_values = {**asdict(knobs), "samples": samples}
    return LightBake(arrays, knob_values, meshes, scene_digest(scene), seconds)


def _mesh_bake(need, digest: str, blocks: np.ndarray, reuse: _Reuse, per_point: float):
    """The report's line of one mesh; ``per_point``: the bake's time per traced point (every
    point costs about the same)."""
    points = int(blocks[need.mesh + 1] - blocks[need.mesh]) if need.anything else 0
    kept = need.mesh in reuse.kept
    return MeshBake(
        name=need.name,
        digest=digest,
        baked=need.anything,
        shadows=need.shadows,
        interreflection=need.interreflection,
        reason=need.reason,
        neighbours=list(need.neighbours),
        points=points,
        seconds=0.0 if kept else round(per_point * points, 3),
        kept=kept,
        rebaked=reuse.why.get(need.mesh, ""),
    )

"""The OpenCL final render over a plain-array scene (scene/scene.py).

Two modes: deterministic direct lighting (exactly the given virtual lights, plus Blender's
lights) and Monte Carlo path tracing (the World sampled with MIS, bounces). Shadow rays and
area-light code only where the scene analysis says they can matter (scene/analysis.py),
compiled as ``-D`` variants and cached. Work goes in launches sized by measured cost
(render/launch.py plans them), so progress is reported and a cancel honoured at any sample
count; device memory holds one band of passes at a time.

Anti-aliasing follows the film's pixel filter (render/pixel_filter.py; Blender's default,
Blackman-Harris 1.5 px, unless told otherwise; ``film=None``: every ray through the pixel
centre, the images of before): the Sampled mode places each sample in the filter's footprint
by importance sampling; the Virtual Lights mode takes ``aa_samples`` subpixel positions.

The film and the materials' texel filter change between renders (``set_film``,
``set_texel_filter``: the accuracy report's rungs) without a second BVH build or table upload;
cl/frame.py ``render_frame`` runs F12's sequence of calls for one frame.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ..core.codecs.gpu_fit import fit_for_gpu
from ..core.codecs.packed import pack
from ..core.sampling.btf_importance import sampled_by_table
from ..core.sampling.envmap import VirtualLights
from ..core.sampling.world_pyramid import lobe_defines, world_pyramid
from ..render.adaptive import AdaptiveSampling
from ..render.launch import LaunchPlan
from ..render.pixel_filter import FILTER_TABLE_SIZE, PixelFilter, r2_points
from ..scene.analysis import SceneFeatures, analyse
from ..scene.bake_points import BIN_MARGIN
from ..scene.geometry_cache import cached_bvh
from ..scene.lights import pack_lights
from ..scene.scene import Scene
from .context import CLContext
from .kernel_args import ArgumentKernel
from .programs import build_program

KERNELS = "render_direct.cl"  # both final-render kernels


def program_defines(features) -> dict[str, int]:
    """The final render's build defines: the scene's effects (scene/analysis.py) and the size
    of the film filter's table (render/pixel_filter.py, read by kernels/include/btf_filter.h:
    one definition, arriving as a define). What ``is_cached`` must be asked with too."""
    # The light bake's view-bin inset (scene/bake_points.py), in per mille: an integer define,
    # so no double literal reaches a device without doubles.
    margin = round(BIN_MARGIN * 1000)
    return {
        **features.defines(),
        "FILTER_TABLE_SIZE": FILTER_TABLE_SIZE,
        "BAKE_BIN_MARGIN_PERMILLE": margin,
        **lobe_defines(),
    }


LOCAL_SIZE = (16, 1)  # work-group shape, fixed: see CLRenderer._global_size
DEFAULT_FILM = PixelFilter()  # Blender's default film: Blackman-Harris, 1.5 px


def device_table_bytes(cl_context: CLContext) -> int:
    """The largest table buffer the device takes (OpenCL's CL_DEVICE_MAX_MEM_ALLOC_SIZE)."""
    return int(cl_context.device.max_mem_alloc_size)


@dataclass
class RenderPasses:
    """combined: (h, w, 4) RGBA; depth: (h, w); normal: (h, w, 3); uv: (h, w, 2); row 0 = top."""

    combined: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    uv: np.ndarray


class AdaptiveFilm:
    """The host half of adaptive sampling for one Sampled render (render/adaptive.py has the
    rule): the whole image's half sums and which pixels still sample, the device's mask of them
    (read by every launch) and the band buffer the kernel writes the half into."""

    def __init__(self, renderer: CLRenderer, schedule: AdaptiveSampling, max_rows: int):
        cl = renderer.cl
        h, w = renderer.height, renderer.width
        self.renderer, self.schedule = renderer, schedule
        self.active = np.ones((h, w), bool)
        self.half = np.zeros((h, w, 4), np.float32)  # RGB sum of the half, and its count
        self.half_buffer = cl.Buffer(
            renderer.ctx.context, cl.mem_flags.WRITE_ONLY, max_rows * w * 16
        )
        self.mask = renderer._buffer(self.active.ravel(), np.uint8)

    def kernel_args(self) -> list:
        """render_env_mis's last arguments after ``combined``: half, active, adaptive."""
        return [self.half_buffer, self.mask, np.int32(1)]

    def gather(self, row0: int, rows: int) -> None:
        """Add the launch's half sums for rows [row0, row0 + rows) (0 where a pixel stopped)."""
        w = self.renderer.width
        host = np.empty((rows, w, 4), dtype=np.float32)
        self.renderer.cl.enqueue_copy(self.renderer.ctx.queue, host, self.half_buffer)
        self.half[row0 : row0 + rows] += host

    def check(self, sums: np.ndarray, counts: np.ndarray) -> np.ndarray:
        """After a pass: stop the pixels that converged, send the mask to the device and return
        (h,) the active pixels per row. ``sums``: (h, w, 4) sums of every sample; ``counts``:
        (h, w) samples per pixel."""
        n = np.maximum(counts, 1)[..., None].astype(np.float32)
        half_n = np.maximum(self.half[..., 3:], 1.0)
        self.active = self.schedule.still_active(
            self.active, sums[..., :3] / n, self.half[..., :3] / half_n, self.half[..., 3], counts
        )
        self.mask = self.renderer._buffer(self.active.ravel(), np.uint8)
        return self.active.sum(axis=1)


class CLRenderer:
    #: The Sampled mode's Noise Threshold (render/adaptive.py): pixels whose noise estimate
    #: falls below it stop taking samples; 0: off, every pixel takes every sample. F12 sets
    #: the scene's (render_frame); a renderer used on its own samples every pixel fully.
    adaptive_threshold: float = 0.0
    #: (h, w) int64: the samples each pixel of the last render_sampled took.
    sample_counts: np.ndarray | None = None

    def __init__(
        self,
        scene: Scene,
        width: int,
        height: int,
        cl_context: CLContext,
        features: SceneFeatures | None = None,
        film: PixelFilter | None = DEFAULT_FILM,
        importance_tables: bool = False,
    ):
        """``importance_tables``: pack the measured codecs' sampling tables now, for a Sampled
        render to come (F12 in that mode: packing without them first, then again with them
        when render_sampled asks, cost the demo's F12 15 ms; the direct kernel never reads
        them, so its images are the same either way)."""
        import pyopencl as cl

        self.cl = cl
        self.scene, self.width, self.height, self.ctx = scene, width, height, cl_context
        self.features = features or analyse(scene)
        #: True: launches split the same way every run (bit-identical frames, render/launch.py);
        #: None: as BTF_FIXED_LAUNCHES says; False: sized by measured cost.
        self.fixed_launch_split: bool | None = None
        #: Film › Transparent: no World where camera rays miss; alpha = coverage (premultiplied).
        self.transparent = False
        #: What the caller should tell the user: materials reduced to fit the device.
        self.notes: list[str] = []
        self._fitted: list | None = None  # _device_btfs
        #: The Sampled mode samples measured BTFs by their tables (core/sampling/btf_importance.py,
        #: built on the first Sampled render); False: cosine sampling, as before them.
        self.importance_sampling = True
        #: The Sampled mode's Clamp Indirect (kernels/render_direct.cl clamp_indirect): a path's
        #: light after its first bounce scaled to at most this per channel; 0: off (unbiased).
        #: F12 sets the scene's (render_frame); a renderer used on its own stays unbiased.
        self.clamp_indirect = 0.0
        #: The Sampled mode's Samples per Camera Ray (kernels/render_direct.cl camera_split):
        #: consecutive samples of a pixel sharing one filtered camera ray; 1: a ray each.
        #: F12 sets the scene's (render_frame); a renderer used on its own keeps 1.
        self.samples_per_camera_ray = 1
        self._packed_importance = False
        program = build_program(
            cl_context.context, cl_context.device, KERNELS, program_defines(self.features)
        )
        self.program = program  # the light bake's kernels are in it too (cl/bake.py)
        self.kernel = cl.Kernel(program, "render_direct")
        self.kernel_mis = cl.Kernel(program, "render_env_mis")
        self._upload_geometry()
        self._upload_materials(importance_tables)
        self._film: PixelFilter | None = None
        self.filter_table = None  # set_film's buffer
        self.set_film(film)
        self._texel_filter: str | None = None
        self._upload_blocks()
        env = scene.environment
        rgba = env.rgba32()
        self.env = self._buffer(rgba.ravel(), np.float32)
        self.scene_lights = self._buffer(pack_lights(scene.lights).ravel(), np.float32)
        self.scene_light_count = np.int32(len(scene.lights))
        #: The Sampled mode's environment draws from MIS-compensated tables
        #: (core/sampling/envmap.py ``Environment.mis_tables``); False: the plain tables, as
        #: before them (comparisons, docs/accuracy.md).
        self.mis_compensation = True
        #: The Sampled mode draws a map's sun on its own (``Environment.sun_tables``; with
        #: mis_compensation only); False: from the whole table, as before (comparisons).
        self.sun_sampling = True
        #: At a glossy camera vertex under a map with a sun, one more draw from the map
        #: restricted to a window around the lobe's mirror direction (``Environment.lobe_window``;
        #: sun_sampling only); False: as before (comparisons).
        self.lobe_window = True
        self._env_tables: dict[tuple[bool, bool, bool], list] = {}
        self._open_bvh: list | None = None  # open_bvh's buffers, on first use
        self._pyramid: list | None = None  # lobe_args's pyramid, on first use

    def _buffer(self, array, dtype):
        mf = self.cl.mem_flags
        data = np.ascontiguousarray(array, dtype=dtype)
        if data.size == 0:
            data = np.zeros(1, dtype=dtype)  # OpenCL buffers cannot be empty
        return self.cl.Buffer(self.ctx.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=data)

    def _upload_geometry(self) -> None:
        corners, materials = [], []
        for i, mesh in enumerate(self.scene.meshes):
            data = mesh.world_space_corners()
            corners.append(data)
            # per triangle: its mesh's row of the material blocks (kernels/include/btf_surface.h)
            materials.append(np.full(len(data) // 3, i, dtype=np.int32))
        corners = np.concatenate(corners) if corners else np.zeros((0, 12), np.float32)
        tri_material = np.concatenate(materials) if materials else np.zeros(0, np.int32)
        tris = corners.reshape(-1, 3, 12)
        if len(tris):
            bvh = cached_bvh(tris[:, :, :3])  # from the disk when built before
            tris, tri_material = tris[bvh.order], tri_material[bvh.order]
            self.triangle_order = bvh.order  # the light bake's tables follow the BVH's order
            bounds, links = bvh.bounds, bvh.links
            extent = float(np.ptp(tris[:, :, :3].reshape(-1, 3), axis=0).max())
        else:  # an empty scene: one empty leaf that nothing can hit
            self.triangle_order = np.zeros(0, np.int64)
            bounds = np.array([[1, 1, 1, -1, -1, -1]], dtype=np.float32)
            links = np.array([[0, 0]], dtype=np.int32)
            extent = 1.0
        self.triangle_count = len(tris)
        # Shadow-ray offset relative to the scene size: works from millimetres to kilometres.
        self.eps = np.float32(max(extent, 1e-6) * 1e-5)
        self.bounds = self._buffer(bounds.ravel(), np.float32)
        self.links = self._buffer(links.ravel(), np.int32)
        self.corners = self._buffer(tris.ravel(), np.float32)
        self.tri_material = self._buffer(tri_material, np.int32)

    def _device_btfs(self) -> list:
        """The scene's BTFs as the device takes them, fitted once (the materials are packed
        again when the Sampled mode adds sampling tables). One too large for one buffer or for
        float32 offsets (the packed layout is the GLSL one) becomes a reduced-resolution copy,
        as the viewport draws it, with a note saying so."""
        if self._fitted is None:
            self._fitted = []
            for material in self.scene.materials:
                btf, note = fit_for_gpu(
                    material.btf, 1 << 30, device_table_bytes(self.ctx), "the final render traces"
                )
                if note:
                    self.notes.append(note)
                self._fitted.append(btf)
        return self._fitted

    def _upload_materials(self, importance: bool = False) -> None:
        """``importance``: with the measured codecs' sampling tables (the Sampled mode's)."""
        ints, floats, offsets = [], [], []
        i_cursor = f_cursor = 0
        self._packed_importance = importance
        for btf in self._device_btfs():
            packed = pack(btf, importance=importance)
            ints.append(packed.ints.ravel())
            floats.append(packed.floats.ravel())
            offsets += [i_cursor, f_cursor]
            i_cursor += packed.ints.size
            f_cursor += packed.floats.size
        self.ints = self._buffer(np.concatenate(ints) if ints else [], np.float32)
        self.floats = self._buffer(np.concatenate(floats) if floats else [], np.float32)
        self.material_offsets = self._buffer(offsets, np.int32)

    @property
    def film(self) -> PixelFilter | None:
        """The pixel filter the renders follow (None: pixel centres)."""
        return self._film

    def set_film(self, film: PixelFilter | None) -> None:
        """Render with this film from now on. Only its inverse-CDF table travels (zeros without
        a film: every offset the pixel centre)."""
        if self.filter_table is not None and film == self._film:
            return
        table = np.zeros(FILTER_TABLE_SIZE) if film is None else film.table()
        self.filter_table = self._buffer(table, np.float32)
        self._film = film

    @property
    def texel_filter(self) -> str | None:
        """The texel filter every material is drawn with; None: each material's own."""
        return self._texel_filter

    def set_texel_filter(self, texel_filter: str | None) -> None:
        """Draw every material with this texel filter ('LINEAR' | 'NEAREST') from now on; None:
        each material's own. Only the material parameter blocks travel, where the filter is a
        slot; the packed tables are the same for both filters."""
        if texel_filter != self._texel_filter:
            self._upload_blocks(texel_filter)

    def _upload_blocks(self, texel_filter: str | None = None) -> None:
        """One parameter block per mesh (core/codecs/packed.py MATERIAL_BLOCK: mapping, texel
        filter,
        exposure), with every material's texel filter replaced unless ``texel_filter`` is None."""
        scene = self.scene
        if texel_filter is not None:
            materials = [replace(m, texel_filter=texel_filter) for m in scene.materials]
            scene = replace(scene, materials=materials)
        # Another name raises here (core/mapping.py Placement), before any state changes.
        blocks = scene.material_blocks()
        self.material_params = self._buffer(blocks.ravel(), np.float32)
        self._texel_filter = texel_filter

    def _scene_args(self) -> list:
        """Kernel arguments shared by both modes, after the view: geometry and materials."""
        return [
            np.int32(self.triangle_count),
            self.bounds,
            self.links,
            self.corners,
            self.tri_material,
            self.ints,
            self.floats,
            self.material_offsets,
            self.material_params,
        ]

    def _env_args(self) -> list:
        """The World and Blender's lights."""
        env = self.scene.environment
        return [
            self.env,
            np.int32(env.width),
            np.int32(env.height),
            np.array([env.rotation_z_rad, 1.0], dtype=np.float32),
            self.scene_lights,
            self.scene_light_count,
        ]

    def open_bvh(self) -> list:
        """A BVH (bounds, links, corners) of one degenerate triangle, which no ray meets: the
        kernels' empty scene, where the light bake traces an analytic point's unshadowed light
        (include/btf_bake.h ``bake_over_unshadowed``) and Blender's lights reach it
        unshadowed. Uploaded on first use, once per renderer."""
        if self._open_bvh is None:
            self._open_bvh = [
                self._buffer(np.zeros(6), np.float32),
                self._buffer(np.array([0, 1]), np.int32),
                self._buffer(np.zeros(36), np.float32),
            ]
        return self._open_bvh

    def lobe_args(self) -> list:
        """What kernels/include/btf_lobe.h ``lobe_light`` reads besides the surface point and
        the World's map: the World's pyramid and its level count
        (core/sampling/world_pyramid.py, uploaded on first use, once per renderer), Blender's
        lights, and ``open_bvh``'s empty scene."""
        if self._pyramid is None:
            pyramid = world_pyramid(self.scene.environment)
            self._pyramid = [
                self._buffer(pyramid.rgba.ravel(), np.float32),
                np.int32(pyramid.levels),
            ]
        return [*self._pyramid, self.scene_lights, self.scene_light_count, *self.open_bvh()]

    def plain_env_tables(self) -> list:
        """The World's plain tables (envmap.py ``Environment.tables``, whose draws reach every
        direction with light) as row_cdf, col_cdf, row_pdf, col_pdf buffers: the light bake's
        direction draws (cl/bake.py). The upload an uncompensated Sampled render uses."""
        return self._next_event_tables(compensated=False)[:4]

    def _next_event_tables(self, compensated: bool | None = None) -> list:
        """The environment's tables for the Sampled mode's draws, exactly those of
        core/sampling/envmap.py, and its sun's (the kernel's sun_cdf, sun_pixels, a
        per-pixel probability that is 0 outside the sun, the sun's pixel count (0 for none)
        and its share of the compensated weight) and the lobe window's block sums and block
        size (0 for none), uploaded on first use. ``compensated``: None, as the renderer's
        ``mis_compensation`` says."""
        compensated = bool(self.mis_compensation if compensated is None else compensated)
        with_sun = compensated and bool(self.sun_sampling)
        key = (compensated, with_sun, with_sun and bool(self.lobe_window))
        if key not in self._env_tables:
            env = self.scene.environment
            sun = None
            if key[1]:
                tables, sun = env.sun_tables
            else:
                tables = env.mis_tables if compensated else env.tables
            buffers = [
                self._buffer(a.ravel(), np.float32)
                for a in (tables.row_cdf, tables.col_cdf, tables.row_pdf, tables.col_pdf)
            ]
            if sun is None:  # the kernel reads none of these
                buffers += [self._buffer(np.zeros(1), dtype) for dtype in (np.float32, np.int32)]
                buffers += [self._buffer(np.zeros(1), np.float32), np.int32(0), np.float32(0)]
            else:
                probability = np.zeros(env.width * env.height, dtype=np.float32)
                probability[sun.pixels] = sun.probability
                buffers += [
                    self._buffer(sun.cdf, np.float32),
                    self._buffer(sun.pixels, np.int32),
                    self._buffer(probability, np.float32),
                    np.int32(len(sun.pixels)),
                    np.float32(sun.share),
                ]
            window = env.lobe_window if key[2] else None
            if window is None:  # block 0: the kernel draws no window and reads neither
                buffers += [self._buffer(np.zeros(1), np.float32) for _ in range(2)]
                buffers += [np.int32(0)]
            else:
                buffers += [
                    self._buffer(window.row_pdf, np.float32),
                    self._buffer(window.cdf.ravel(), np.float32),
                    np.int32(window.block),
                ]
            self._env_tables[key] = buffers
        return self._env_tables[key]

    def _world_from_clip(self):
        cam = self.scene.camera
        world_from_clip = np.linalg.inv(cam.clip_from_world(self.width / self.height))
        return self._buffer(world_from_clip.ravel(), np.float32)

    def _global_size(self, rows: int) -> tuple[int, int]:
        """Launch shape for ``rows`` rows: width rounded up to LOCAL_SIZE (the kernels skip
        pixels past the edge). A fixed local size matters: PoCL compiles a kernel anew for
        every work-group shape it picks itself, and band heights vary."""
        lx = LOCAL_SIZE[0]
        return (-(-self.width // lx) * lx, rows)

    def _render_in_launches(
        self,
        launch,
        channels: tuple[int, ...],
        progress,
        samples: int = 1,
        preview=None,
        plan: LaunchPlan | None = None,
        film: AdaptiveFilm | None = None,
    ) -> list[np.ndarray]:
        """Render in launches of (rows, samples) planned by render/launch.py from measured cost,
        so that each takes about LAUNCH_SECONDS however heavy a pixel is (lights, samples,
        bounces): progress is reported and a cancel honoured between launches.

        ``launch(row0, rows, first_sample, count, buffers)`` enqueues the kernel for those rows
        and samples [first_sample, first_sample + count), writing per-pixel means, one buffer
        per entry of ``channels``. Samples go in passes over the whole image (each pass about
        PASS_SECONDS); ``preview(images)`` sees the image after the first pass, then after a
        pass at most every half PASS_SECONDS (read it during the call: the arrays may be
        reused). ``progress``
        returning False stops: rows keep the samples they have (rows never reached stay black).
        ``plan``: the launches (default: ``samples`` samples by the renderer's split);
        ``film``: adaptive sampling, whose check after a pass stops converged pixels.
        Returns (h, w, k) arrays averaged over every sample rendered; ``sample_counts`` holds
        (h, w) the samples each pixel took."""
        cl = self.cl
        w, h = self.width, self.height
        if plan is None:
            plan = LaunchPlan(w, h, samples, fixed=self.fixed_launch_split)
        mf = cl.mem_flags
        buffers = [
            cl.Buffer(self.ctx.context, mf.WRITE_ONLY, plan.max_rows * w * 4 * k) for k in channels
        ]
        sums = [np.zeros((h, w, k), np.float32) for k in channels]
        counts = np.zeros((h, w), np.int64)  # samples rendered per pixel
        self.sample_counts = counts

        def images():
            if counts.max() <= 1:  # one sample (the deterministic mode): sums are the means
                return sums
            weight = (1.0 / np.maximum(counts, 1)).astype(np.float32)[..., None]
            return [total * weight for total in sums]

        shown = -np.inf  # when the last preview was shown: the first pass's always is
        for step in plan:
            rows, count = slice(step.row0, step.row0 + step.rows), step.samples
            t0 = time.perf_counter()
            launch(step.row0, step.rows, step.first_sample, count, buffers)
            for buf, total in zip(buffers, sums, strict=True):
                host = np.empty((step.rows, w, total.shape[2]), dtype=np.float32)
                cl.enqueue_copy(self.ctx.queue, host, buf)  # waits for the kernel
                total[rows] += host * count  # stopped pixels wrote 0: their sums stay
            if film is None:
                counts[rows] += count
            else:
                film.gather(step.row0, step.rows)
                counts[rows] += count * film.active[rows]
            plan.record(step, time.perf_counter() - t0)
            if film is not None and step.ends_pass:
                if film.schedule.checks_at(step.first_sample + count):
                    plan.set_active_rows(film.check(sums[0], counts))
            if progress is not None and not progress(step.done):
                return images()
            if preview is not None and step.ends_pass and not step.last:
                # At most about twice a pass's time: adaptive sampling ends a pass at every
                # convergence check, often a few ms apart, and each preview is a copy of the
                # whole image into Blender (the demo at 64 × 48, adaptive, 1024 samples: 62
                # previews, 70 ms of its 1.04 s).
                if time.perf_counter() - shown >= plan.pass_seconds / 2:
                    preview(images())
                    shown = time.perf_counter()
        return images()

    def render_direct(
        self,
        lights: VirtualLights,
        progress: Callable[[float], bool] | None = None,
        aa_samples: int = 1,
        split_lights: bool = True,
    ) -> RenderPasses:
        """All passes from exactly these lights (deterministic). With a film filter and
        ``aa_samples`` > 1, Combined is the mean over that many positions in the filter's
        footprint (R2 points rotated per pixel, through the filter's inverse CDF; 1: the pixel
        centre); ``split_lights`` lights each
        subpixel with its own consecutive block of the lights (the cost of one ray per pixel;
        where there are fewer lights than subpixels every subpixel sees all of them), else each
        with all of them (``aa_samples`` times the cost). Depth, Normal and UV stay at the
        pixel centre."""
        w, h = self.width, self.height
        cam = self.scene.camera
        axis = -cam.world_from_camera[:3, 2]
        forward = np.array([*axis, -float(axis @ cam.position)], dtype=np.float32)
        lights_buf = self._buffer(lights.packed().ravel(), np.float32)
        head = [np.int32(w), np.int32(h)]
        n_lights = len(lights.pdf)
        aa = max(int(aa_samples), 1) if self.film is not None else 1
        points = self._buffer(r2_points(aa).ravel(), np.float32)  # rotated per pixel there
        split = bool(split_lights) and n_lights >= aa
        film_args = [
            points,
            np.int32(aa),
            np.int32(split),
            self.filter_table,
            np.int32(self.transparent),
        ]
        tail_args = [lights_buf, np.int32(n_lights), self.eps, *self._env_args(), *film_args]
        wfc = self._world_from_clip()

        def launch(row0, band, _first, _count, buffers):
            self.kernel(
                self.ctx.queue,
                self._global_size(band),
                LOCAL_SIZE,
                *head,
                np.int32(row0),
                wfc,
                forward,
                *self._scene_args(),
                *tail_args,
                *buffers,
            )

        combined, depth, normal, uv = self._render_in_launches(launch, (4, 1, 3, 2), progress)
        return RenderPasses(combined, depth[..., 0], normal, uv)

    def prepare_sampled(self) -> None:
        """Pack the measured codecs' sampling tables where the Sampled mode's paths read them
        (render_sampled and the light bake, cl/bake.py)."""
        want = self.importance_sampling and any(
            sampled_by_table(m.btf) for m in self.scene.materials
        )
        if self._packed_importance != want:  # pack again only where a table changes anything
            self._upload_materials(want)

    def render_sampled(
        self,
        samples: int,
        seed: int = 0,
        progress: Callable[[float], bool] | None = None,
        max_bounces: int = 0,
        preview: Callable[[np.ndarray], None] | None = None,
    ) -> np.ndarray:
        """(h, w, 4) Combined by path tracing: ``samples`` paths per pixel; at every vertex one
        environment sample (at a glossy camera vertex one more of the map's sun, where it has
        one: ``sun_sampling``) and one from the BTF's sampling, with MIS (power heuristic); up to
        ``max_bounces`` indirect reflections (none where the scene analysis finds no surface
        that can see another), Russian roulette after the second. Samples are rendered in
        progressive passes (``preview`` sees each); how they are split changes no sample (each
        sample's random points depend only on its index), only the rounding of the sums:
        ``fixed_launch_split`` makes frames bit-identical between runs. With a film
        filter each sample's camera ray goes through its own point of the filter's footprint,
        drawn with the filter's distribution (the mean converges to the filtered image).
        Measured BTFs are sampled by their tables unless ``importance_sampling`` is False;
        a path's indirect light is clamped at ``clamp_indirect`` when it is above 0; with a
        film, ``samples_per_camera_ray`` consecutive samples share a camera ray. With an
        ``adaptive_threshold`` above 0, pixels whose noise falls below it stop early
        (render/adaptive.py); ``sample_counts`` says how many samples each pixel took."""
        w, h = self.width, self.height
        self.prepare_sampled()
        wfc = self._world_from_clip()
        # No bounces where nothing can be reflected (the analysis' single-convex-mesh rule).
        bounces = max(max_bounces, 0) if self.features.shadows else 0
        world_args = [self.eps, *self._env_args(), *self._next_event_tables()]
        film_args = [
            np.int32(self.film is not None),
            self.filter_table,
            np.int32(self.transparent),
        ]
        schedule = AdaptiveSampling.for_render(self.adaptive_threshold, samples)
        plan = LaunchPlan(
            w,
            h,
            samples,
            fixed=self.fixed_launch_split,
            next_check=None if schedule is None else schedule.next_check,
        )
        adaptive = None if schedule is None else AdaptiveFilm(self, schedule, plan.max_rows)

        # Adaptive sampling off: the kernel neither reads nor writes these.
        idle = [self._buffer(np.zeros(4), np.float32), self._buffer(np.zeros(1), np.uint8)]

        def adaptive_args() -> list:
            if adaptive is None:
                return [*idle, np.int32(0)]
            return adaptive.kernel_args()  # its mask changes after every check

        # The same objects in every launch: ArgumentKernel sets only what a launch changes.
        head, scene_args = [np.int32(w), np.int32(h)], self._scene_args()
        path_args = [
            np.uint32(seed),
            np.int32(bounces),
            np.float32(max(self.clamp_indirect, 0.0)),
            np.int32(max(int(self.samples_per_camera_ray), 1)),
            *film_args,
        ]
        kernel = ArgumentKernel(self.kernel_mis)

        def launch(row0, band, first, count, buffers):
            kernel(
                self.ctx.queue,
                self._global_size(band),
                LOCAL_SIZE,
                *head,
                np.int32(row0),
                wfc,
                *scene_args,
                *world_args,
                np.int32(first),
                np.int32(count),
                *path_args,
                *buffers,
                *adaptive_args(),
            )

        show = None if preview is None else (lambda images: preview(images[0]))
        (combined,) = self._render_in_launches(
            launch, (4,), progress, samples, show, plan=plan, film=adaptive
        )
        return combined

"""The one progressive drawer: a plain-array scene (scene/scene.py) drawn with the GLSL shaders
over a device adapter (gl/device.py), for any number of views.

Per view and per restart: the World into the view's background target, a depth pre-pass into
its accumulation target; then per call, a batch of K virtual lights added on the visible
surface (depth test EQUAL, additive blending); the resolve divides the sum by the lights added
so far where a surface was drawn and shows the World elsewhere (shaders/resolve_frag.glsl).

Anti-aliasing (a view's ``jitter``: the film's pixel filter): batch i is drawn with the
projection moved by the filter's i-th subpixel offset (render/pixel_filter.py, R2 points
through the filter's inverse CDF; batch 0 at the pixel centre), as EEVEE's temporal
anti-aliasing does. Each jittered batch is drawn whole into a scratch target — the World
through the same offset × the batch's light count, its own depth pre-pass, the surfaces' light
sums replacing the World where they are — and added to the accumulation, so the resolve's
division mixes surfaces and World by coverage. A view resolved over a transparent background
(``jitter_world`` False) gets no World there: its silhouettes darken by their coverage. The
accumulation converges to the filtered image: F12's Virtual Lights mode with the lights split
over as many subpixels renders exactly it (same offsets, same order).

A light bake (``Scene.light_bake``, render/light_bake.py) is played back on the meshes it still
holds (render/bake_playback.py): their fragments add the bake's light × the batch's light
count, as Blender's lights are added, so the resolve shows them converged from the first batch
and their cost does not grow with the lights. ``bake_status`` says which meshes play it back
and which are stale (drawn with live light).

The drawer holds what belongs to the scene (programs, BTF tables, vertex buffers, the World,
Blender's lights, the light bake's tables); a ``ViewAccumulation`` holds what belongs to one
view (its targets, its virtual lights, its progress, the camera its accumulation was started
with). Two eyes are two views of one drawer.
"""

from __future__ import annotations

import itertools
import logging
from typing import Any

import numpy as np

from ..core.codecs.gpu_fit import MAX_TEXTURE_SIZE, fit_for_gpu
from ..core.codecs.packed import layout_stream, pack
from ..core.mat4 import inverse
from ..core.sampling.envmap import VirtualLights
from ..core.sampling.world_pyramid import LOBE_SAMPLES, WorldPyramid, world_pyramid
from ..render import bake_playback
from ..render.pixel_filter import PixelFilter, subpixel_offset
from ..render.progressive import ProgressiveState
from ..scene.lights import pack_lights
from ..scene.scene import Mesh, Scene
from .device import ADD_LIGHTS, DEFAULT_STATE, DEPTH_PREPASS, Device, DrawState
from .interface import BACKGROUND_SHADER, RESOLVE_SHADER, SURFACE_SHADER

log = logging.getLogger(__name__)

# A jittered batch added onto the accumulation: every pixel, no depth.
ADD_BATCH = DrawState(depth_write=False, blend="ADD")
# The World behind a jittered batch: no depth written, so the pre-pass still sees "far".
WORLD_UNDER = DrawState(depth_write=False)
# A jittered batch's lights over that World: the nearest surface (one per pixel) replaces it.
REPLACE_LIGHTS = DrawState(depth_test="EQUAL", depth_write=False)

MAX_SIZE = 16384  # pixels per side: beyond any GPU's texture limit
# Lights one draw loops over at most. Mesa's llvmpipe loses light on the dense decode when one
# fragment loops over 255 or more (relative RMSE 1.4 % at 256 lights in one draw, 5e-8 at 128,
# on a woven sphere; tests/gl/test_light_batches.py); a larger batch is several draws added up.
MAX_LIGHTS_PER_DRAW = 128
# Each corner's barycentrics in its triangle (of corners 1 and 2): interpolated, the fragment's.
CORNER_BARY = np.array([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)], dtype=np.float32)
# Two triangles covering clip space: one fragment per pixel of the bound target.
QUAD = np.array([(-1, -1), (1, -1), (-1, 1), (-1, 1), (1, -1), (1, 1)], dtype=np.float32)
_serials = itertools.count(1)


def check_size(width: int, height: int) -> None:
    if width < 1 or height < 1 or max(width, height) > MAX_SIZE:
        raise ValueError(f"resolution {width}×{height} is outside 1…{MAX_SIZE}")


class ViewAccumulation:
    """One view's progressive image; the caller owns it and may keep it across drawers.

    Targets (device objects, ``width`` × ``height``): ``background`` (RGBA32F, the World),
    ``accumulation`` (RGBA32F with depth: the sum of the light batches, alpha = batches drawn),
    ``output`` (``output_format``: the resolved image). ``state`` counts the lights added;
    ``lights`` is the virtual-light texture; ``clip_from_world`` ((4, 4) float64) and ``camera``
    ((4,) float64, shaders/surface_frag.glsl) are those of the running accumulation, fixed by
    ``ProgressiveDrawer.restart``: every batch must repeat the pre-pass's exact transform for the
    depth test EQUAL to pass. ``jitter`` (a ``PixelFilter``, None: every batch at the pixel
    centre) and ``jitter_world`` (add the World where a jittered batch saw no surface) are read
    at every batch: change them, then restart. ``batches``: batches added since the restart.
    """

    def __init__(self, device: Device, width: int, height: int, output_format: str = "RGBA32F"):
        check_size(width, height)
        self.device = device
        self.width, self.height = width, height
        self.background = device.target(width, height, "RGBA32F", depth=False)
        self.accumulation = device.target(width, height, "RGBA32F", depth=True)
        self.output = device.target(width, height, output_format, depth=False)
        self.state: ProgressiveState | None = None
        self.lights: Any = None
        self.clip_from_world: np.ndarray | None = None
        self.camera: np.ndarray | None = None
        self.jitter: PixelFilter | None = None
        self.jitter_world = True
        self.batches = 0
        self.scratch: Any = None  # one jittered batch (RGBA32F + depth), made on first use

    @property
    def size(self) -> tuple[int, int]:
        return self.width, self.height

    def set_lights(self, lights: VirtualLights, per_pass: int) -> None:
        """Light this view with ``lights``, ``per_pass`` of them per batch. Ends the running
        accumulation: restart before the next batch."""
        n = len(lights.pdf)
        state = ProgressiveState(total=n, per_pass=per_pass)  # checks the counts first
        texture = self.device.texture(lights.packed().reshape(1, 2 * n, 4))  # 2 texels a light
        self.device.release(self.lights)
        self.lights, self.state = texture, state
        self.clip_from_world = self.camera = None

    def read(self) -> np.ndarray:
        """(height, width, 4) float32 resolved image (``ProgressiveDrawer.resolve`` first), row
        0 at the bottom."""
        return self.device.read(self.output)

    def release(self) -> None:
        self.device.release(
            self.background, self.accumulation, self.output, self.lights, self.scratch
        )
        self.background = self.accumulation = self.output = self.lights = self.scratch = None


def _mesh_key(mesh: Mesh) -> tuple:
    """A mesh's upload as it is: the same object-space arrays at the same world matrix."""
    return (id(mesh.positions), np.asarray(mesh.world_from_object).tobytes())


class ProgressiveDrawer:
    """GPU resources of one scene, drawn into views through ``device``.

    Built from a ``previous`` drawer (same device), it keeps every upload whose source did not
    change: BTF tables per BTF object (the exporter caches BTFs by file and fallback colour),
    vertex buffers per mesh (same object-space arrays and world matrix, same place in the light
    bake), the environment per Environment object, the light bake's tables per bake. So a
    viewport edit re-uploads only what the depsgraph reported as changed. ``previous`` hands
    its uploads over: what this drawer does not reuse is released, and ``previous`` must not
    draw again.
    """

    def __init__(self, device: Device, scene: Scene, previous: ProgressiveDrawer | None = None):
        if previous is not None and previous.released:
            raise RuntimeError("the previous drawer was released or already handed over")
        self.device, self.scene = device, scene
        # Unique per drawer for the process's life (id() is reused once a drawer is freed):
        # a view keyed on it knows its lights and depth belong to another scene.
        self.serial = next(_serials)
        self.released = False
        self.surface = device.program(SURFACE_SHADER)
        self.background_program = device.program(BACKGROUND_SHADER)
        self.resolve_program = device.program(RESOLVE_SHADER)
        old_tables = previous._table_uploads if previous else {}
        old_batches = previous._batch_uploads if previous else {}
        old_corners = previous._corners if previous else {}
        # Keyed by id() of the source, with the source kept alive so an id cannot be reused.
        self._table_uploads: dict[int, tuple[object, tuple[Any, Any]]] = {}
        self._batch_uploads: dict[tuple, tuple[object, Any]] = {}
        #: Each mesh's world-space corners (the CPU half of an upload), by the same key as its
        #: arrays: a batch re-uploaded because another of its meshes changed reuses them.
        self._corners: dict[tuple, tuple[object, np.ndarray]] = {}
        self.tables: list[tuple[Any, Any]] = []  # per material: (int table, float table)
        for material in scene.materials:
            key = id(material.btf)
            if key not in self._table_uploads:
                self._table_uploads[key] = old_tables.get(key) or (
                    material.btf,
                    self._upload_tables(material.btf),
                )
            self.tables.append(self._table_uploads[key][1])
        for mesh in scene.meshes:  # world-space corners, kept for the next drawer's batches
            k = _mesh_key(mesh)
            self._corners[k] = (
                self._corners.get(k)
                or old_corners.get(k)
                or (mesh.positions, mesh.world_space_corners())
            )
        self.digests = bake_playback.DigestCache(previous.digests if previous else None)
        self.playback = self._plan_playback(scene)
        self.bake_status = self.playback.status if scene.light_bake is not None else None
        # One batch per material, its meshes' triangles in one vertex buffer, each vertex with
        # its mesh's row of the material blocks (``blk``) and its place in the light bake: a
        # draw per material instead of per mesh, so a scene of many objects costs a few draws
        # per pass (Blender's VR session draws every eye with them). A batch is kept while none
        # of its meshes changed and each keeps its place in the bake.
        self.batches: list[tuple[Any, int]] = []  # (vertices, material index), empty ones out
        groups: dict[int, list[int]] = {}
        for mesh_index, mesh in enumerate(scene.meshes):
            groups.setdefault(mesh.material, []).append(mesh_index)
        for material_index, members in groups.items():
            meshes = [scene.meshes[i] for i in members]
            keys = [_mesh_key(m) for m in meshes]
            places = [self.playback.bake_triangle(i) for i in members]
            key = (material_index, *zip(members, keys, places, strict=True))
            if key not in self._batch_uploads:
                self._batch_uploads[key] = old_batches.get(key) or (
                    [m.positions for m in meshes],
                    self._upload_batch(members, keys, places),
                )
            vertices = self._batch_uploads[key][1]
            if vertices is not None:
                self.batches.append((vertices, material_index))
        # The bake's tables, kept while the same bake is played back.
        old_bake = previous._bake_upload if previous else None
        bake = scene.light_bake if self.playback.first_triangle else None
        if bake is None:
            self._bake_upload = None
        elif old_bake is not None and old_bake[0] is bake:
            self._bake_upload = old_bake
        else:
            index, values = bake_playback.bake_textures(bake)
            self._bake_upload = (bake, (device.texture(index), device.texture(values)))
        env = scene.environment
        if previous is not None and previous.scene.environment is env:
            self.env_tex = previous.env_tex
        else:
            rgba = env.rgba32()
            # Rows go up top first: texture coordinate t = 0 is the first row uploaded, and the
            # shader reads t = 0 as the zenith (shaders/env_lib.glsl). Bilinear, wrapping
            # around the horizontal seam, as Blender's Environment Texture.
            self.env_tex = device.texture(rgba, linear=True, wrap_x=True)
        # The World's pyramid, which baked analytic objects read (shaders/lobe_lib.glsl):
        # uploaded while a bake plays back, kept across drawers of the same World.
        self.pyramid: WorldPyramid | None = None
        self.pyramid_tex = None
        #: Directions per pixel and batch of a baked analytic object's unshadowed light
        #: (shaders/lobe_lib.glsl): the accuracy-for-time knob docs/accuracy.md measures.
        self.lobe_samples = previous.lobe_samples if previous is not None else LOBE_SAMPLES
        if self._bake_upload is not None:
            self.pyramid = world_pyramid(env)
            if previous is not None and previous.pyramid is self.pyramid:
                self.pyramid_tex = previous.pyramid_tex
            else:
                self.pyramid_tex = device.texture(self.pyramid.rgba)
        self.uploads = {
            "tables": len(set(self._table_uploads) - set(old_tables)),
            "meshes": len(set(self._batch_uploads) - set(old_batches)),
        }
        if previous is not None:  # scene-independent: handed over as they are
            self.quad_background, self.quad_resolve = (
                previous.quad_background,
                previous.quad_resolve,
            )
            self.no_lights, self.no_bake = previous.no_lights, previous.no_bake
        else:
            self.quad_background = device.vertices(self.background_program, {"pos": QUAD})
            self.quad_resolve = device.vertices(self.resolve_program, {"pos": QUAD})
            # Bound to the lights sampler before a view has lights (a depth pre-pass reads none).
            self.no_lights = device.texture(np.zeros((1, 2, 4), dtype=np.float32))
            # Bound to the bake's samplers where no mesh plays a bake back (none reads them).
            self.no_bake = device.texture(np.zeros((1, 1, 4), dtype=np.float32))
        # Blender's lights: five RGBA texels each (scene/lights.py), drawn without shadows.
        self.scene_lights_tex = device.texture(pack_lights(scene.lights).reshape(1, -1, 4))
        # Per mesh its material's parameter block (core/codecs/packed.py MATERIAL_BLOCK): mapping,
        # texel filter, exposure (shaders/btf_mapping_lib.glsl), laid out TABLE_WIDTH floats
        # a row as the BTF tables are, so any number of instances fits a texture's height.
        self.blocks_tex = device.texture(layout_stream(scene.material_blocks().ravel()))
        if previous is not None:
            previous._hand_over(self)

    # --- uploads ---------------------------------------------------------------------------
    def _plan_playback(self, scene: Scene) -> bake_playback.BakePlayback:
        """Which meshes play the scene's light bake back (none without one)."""
        bake = scene.light_bake
        if bake is None:
            return bake_playback.BakePlayback(bake_playback.BakeStatus())
        corners = [self._corners[_mesh_key(m)][1] for m in scene.meshes]
        digests = [
            self.digests.mesh(scene, m, _mesh_key(m), c)
            for m, c in zip(scene.meshes, corners, strict=True)
        ]
        max_rows = getattr(self.device, "max_texture_size", MAX_TEXTURE_SIZE)
        return bake_playback.plan(
            bake,
            scene,
            digests,
            [len(c) // 3 for c in corners],
            self.digests.scene(scene),
            max_rows,
        )

    def _upload_tables(self, btf) -> tuple[Any, Any]:
        # Too large for the device's textures: a reduced-resolution copy, said in the log.
        btf, note = fit_for_gpu(btf, getattr(self.device, "max_texture_size", MAX_TEXTURE_SIZE))
        if note:
            log.warning(note)
        packed = pack(btf)
        return self.device.texture(packed.ints), self.device.texture(packed.floats)

    def _upload_batch(self, members: list[int], keys: list[tuple], places: list[int]):
        """One vertex buffer of meshes ``members`` (their indices, rows of the material
        blocks; ``keys``: their corners' keys; ``places``: their first bake triangles, −1 for
        live light), in world space; None when empty."""
        parts, rows, tris = [], [], []
        for index, key, place in zip(members, keys, places, strict=True):
            data = self._corners[key][1]  # (3 × tris, 12)
            parts.append(data)
            rows.append(np.full(len(data), index, dtype=np.float32))
            count = len(data) // 3
            tri = place + np.arange(count) if place >= 0 else np.full(count, -1)
            tris.append(np.repeat(tri, 3).astype(np.float32))
        data = np.concatenate(parts) if parts else np.zeros((0, 12), np.float32)
        if len(data) == 0:
            return None
        attributes = {"pos": data[:, 0:3], "nor": data[:, 3:6], "uv": data[:, 6:8]}
        attributes["tan"] = data[:, 8:12]
        attributes["blk"] = np.concatenate(rows)
        attributes["bake_tri"] = np.concatenate(tris)
        attributes["bake_bary"] = np.tile(CORNER_BARY, (len(data) // 3, 1))
        return self.device.vertices(self.surface, attributes)

    def _owned(self) -> list[Any]:
        objects = [t for _, pair in self._table_uploads.values() for t in pair]
        objects += [v for _, v in self._batch_uploads.values()]
        objects += [self.env_tex, self.quad_background, self.quad_resolve, self.no_lights]
        objects += [self.no_bake, *(self._bake_upload[1] if self._bake_upload else ())]
        objects += [self.pyramid_tex] if self.pyramid_tex is not None else []
        return [*objects, self.scene_lights_tex, self.blocks_tex]

    def _hand_over(self, successor: ProgressiveDrawer) -> None:
        kept = {id(o) for o in successor._owned()}
        self.device.release(*(o for o in self._owned() if id(o) not in kept))
        self._forget()

    def release(self) -> None:
        """Free the scene's uploads (views are released by their owner)."""
        self.device.release(*self._owned())
        self._forget()

    def _forget(self) -> None:
        self._table_uploads, self._batch_uploads, self.tables, self.batches = {}, {}, [], []
        self._corners, self._bake_upload = {}, None
        self.released = True

    # --- drawing ---------------------------------------------------------------------------
    def restart(self, view: ViewAccumulation, clip_from_world: np.ndarray, camera) -> None:
        """Start ``view``'s accumulation from ``clip_from_world`` ((4, 4)) and ``camera`` ((4,):
        position and 1, or direction towards the viewer and 0): the World into its background,
        its accumulation cleared and given the depth the light batches test EQUAL against."""
        if self.released:
            raise RuntimeError("this drawer was released or handed over to a newer one")
        view.clip_from_world = np.array(clip_from_world, dtype=np.float64)
        view.camera = np.array(camera, dtype=np.float64)
        device = self.device
        env = self.scene.environment
        with device.bound(view.background):
            device.set_state(DEFAULT_STATE)
            device.draw(
                self.background_program,
                self.quad_background,
                {
                    "world_from_clip": inverse(view.clip_from_world),
                    "viewport_size": view.size,
                    "env_params": (env.rotation_z_rad, 1.0),
                },
                {"environment": self.env_tex},
            )
        with device.bound(view.accumulation):
            device.clear((0.0, 0.0, 0.0, 0.0))
            if view.jitter is None:  # jittered batches bring their own depth
                self._draw_surfaces(view, 0, 0, DEPTH_PREPASS)
        view.batches = 0
        if view.state is not None:
            view.state.restart()

    def add_batch(self, view: ViewAccumulation) -> int:
        """Add ``view``'s next batch of lights; how many were added (0 once converged)."""
        if view.state is None:
            raise RuntimeError("set the view's lights first")
        if view.clip_from_world is None:
            raise RuntimeError("restart the view first")
        first, count = view.state.next_batch()
        if count and view.jitter is not None:
            self._add_jittered_batch(view, first, count)
        elif count:
            with self.device.bound(view.accumulation):
                self._draw_lights(view, first, count, ADD_LIGHTS)
        if count:
            view.state.advance(count)
            view.batches += 1
        return count

    def _add_jittered_batch(self, view: ViewAccumulation, first: int, count: int) -> None:
        """Lights [first, first + count) seen through the view's next subpixel offset, added
        to the accumulation (module docstring)."""
        device = self.device
        dx, dy = subpixel_offset(view.jitter, view.batches)  # pixels, x right, y down
        w, h = view.size
        # Sampling at +offset is drawing the image moved by −offset: NDC x by −2dx/w, and
        # NDC y (up) by +2dy/h; in clip space x' = x + ox·w, whatever the projection.
        clip_from_clip = np.eye(4)
        clip_from_clip[0, 3], clip_from_clip[1, 3] = -2.0 * dx / w, 2.0 * dy / h
        jittered = clip_from_clip @ view.clip_from_world
        if view.scratch is None:
            view.scratch = device.target(w, h, "RGBA32F", depth=True)
        with device.bound(view.scratch):
            device.clear((0.0, 0.0, 0.0, 0.0))
            if view.jitter_world:  # the World through the same offset, × the batch's lights
                env = self.scene.environment
                device.set_state(WORLD_UNDER)
                device.draw(
                    self.background_program,
                    self.quad_background,
                    {
                        "world_from_clip": inverse(jittered),
                        "viewport_size": view.size,
                        "env_params": (env.rotation_z_rad, float(count)),
                    },
                    {"environment": self.env_tex},
                )
            self._draw_surfaces(view, 0, 0, DEPTH_PREPASS, jittered)
            self._draw_lights(view, first, count, REPLACE_LIGHTS, jittered)
        # The resolve shader copies the batch (÷ 1); where neither a surface nor the World was
        # drawn (transparent) it adds nothing.
        params = (1.0, 0.0 if view.jitter_world else 1.0, 0.0, 0.0)
        with device.bound(view.accumulation):
            device.set_state(ADD_BATCH)
            device.draw(
                self.resolve_program,
                self.quad_resolve,
                {"resolve_params": params},
                {
                    "accumulation": device.target_texture(view.scratch),
                    "background": device.target_texture(view.background),
                },
            )
            device.set_state(DEFAULT_STATE)

    def resolve(self, view: ViewAccumulation, transparent_background: bool = False) -> None:
        """Draw ``view``'s image so far into its output target (``draw_resolved``)."""
        with self.device.bound(view.output):
            self.draw_resolved(view, transparent_background=transparent_background)

    def draw_resolved(
        self,
        view: ViewAccumulation,
        exposure: float = 0.0,
        transparent_background: bool = False,
        state: DrawState = DEFAULT_STATE,
    ) -> None:
        """Draw ``view``'s image so far into the bound framebuffer, which must have the view's
        size (pixels are fetched at the fragment's own coordinates): an eye's framebuffer in
        a draw callback, a swapchain image. ``exposure``: stops, on surfaces and World alike;
        ``transparent_background``: premultiplied alpha 0 where no surface was drawn, to be
        blended (``state``) over what the framebuffer already holds."""
        device = self.device
        done = view.state.done if view.state is not None else 0
        params = (max(done, 1), float(transparent_background), float(exposure), 0.0)
        device.set_state(state)
        device.draw(
            self.resolve_program,
            self.quad_resolve,
            {"resolve_params": params},
            {
                "accumulation": device.target_texture(view.accumulation),
                "background": device.target_texture(view.background),
            },
        )
        if state != DEFAULT_STATE:
            device.set_state(DEFAULT_STATE)

    def _draw_lights(
        self,
        view: ViewAccumulation,
        first: int,
        count: int,
        state: DrawState,
        clip_from_world: np.ndarray | None = None,
    ) -> None:
        """Lights [first, first + count) in draws of at most ``MAX_LIGHTS_PER_DRAW``: the
        first with ``state``, the others added onto it (the same surfaces, depth EQUAL)."""
        for start in range(first, first + count, MAX_LIGHTS_PER_DRAW):
            n = min(MAX_LIGHTS_PER_DRAW, first + count - start)
            self._draw_surfaces(
                view, start, n, state if start == first else ADD_LIGHTS, clip_from_world
            )

    def _draw_surfaces(
        self,
        view: ViewAccumulation,
        first: int,
        count: int,
        state: DrawState,
        clip_from_world: np.ndarray | None = None,
    ):
        device = self.device
        if clip_from_world is None:
            clip_from_world = view.clip_from_world
        lights = view.lights if view.lights is not None else self.no_lights
        bake_index, bake_values = self._bake_upload[1] if self._bake_upload else (self.no_bake,) * 2
        pyramid = self.pyramid_tex if self.pyramid_tex is not None else self.no_bake
        p = self.pyramid
        world = (
            (self.scene.environment.rotation_z_rad, p.levels, p.width, p.height)
            if p is not None
            else (0.0, 0.0, 1.0, 1.0)
        )
        device.set_state(state)
        try:
            light_range = (first, count, self.lobe_samples, len(self.scene.lights))
            for vertices, material_index in self.batches:
                ints, floats = self.tables[material_index]
                uniforms = {
                    "clip_from_world": clip_from_world,
                    "camera": view.camera,
                    "light_range": light_range,
                    "world": world,
                }
                samplers = {
                    "btf_int_tables": ints,
                    "btf_float_tables": floats,
                    "lights": lights,
                    "scene_lights": self.scene_lights_tex,
                    "material_blocks": self.blocks_tex,
                    "bake_index": bake_index,
                    "bake_values": bake_values,
                    "world_pyramid": pyramid,
                }
                device.draw(self.surface, vertices, uniforms, samplers)
        finally:
            device.set_state(DEFAULT_STATE)

"""Build BTF Material Library (File › Export): a folder of BTF sources and the synthetic
presets → an asset library for Blender's Asset Browser.

One material asset per source in one .blend in the library folder: the material as Import
makes it (Box mapping in object space at real-world size, so it works on any mesh), its
preview rendered by this engine's F12 (a swatch on a sphere or a cloth under Blender's
neutral studio light, transparent film), a description and tags, and a catalog by kind of
source in ``blender_assets.cats.txt`` (``BTF/BTFbase``, ``BTF/Synthetic``...; catalog ids are
derived from the catalog path, so a rebuild keeps them). The presets are written as ``.btfm``
files into the library's ``synthetic`` folder (procedural ones tabulated first: the GPU back
ends draw tables). Each material's source is stored relative to the library .blend, so the
library folder moved with its sources (or with ``copy_sources``, alone) still finds them.

Applying an asset: Blender copies a material's strings as they are, so a source relative to
the library would be read relative to the user's file. ``blend_import_pre/post`` (Blender
4.3+) rebase the sources of the BTF materials an append brings (the asset, or the materials
of an appended object) onto the open file: relative when it is saved and Preferences › File
Paths › Default Relative Paths is on, else absolute (``paths.py``'s save handler takes it
from there). Linked materials, which the user's file does not store, get their library's
absolute path in memory, again after each file load (``load_post``).

The open file keeps nothing: previews render in a scene of their own that is removed
afterwards (the Render Result shows the last preview), the assets are made in
``bpy.data.temp_data()`` and written with ``libraries.write`` (atomically). Progress shows in
the status bar; Esc cancels between sources (nothing written; presets' .btfm files already
written stay); a source that fails is reported and the rest are built.

Render BTF Preview (Material Properties › BTF › Asset Preview) renders one material's preview
the same way and stores it with ``ID.preview_ensure()``: what the Asset Browser shows after
Mark as Asset.
"""

from __future__ import annotations

import logging
import os
import tempfile
import uuid
from dataclasses import dataclass
from pathlib import Path

import bmesh
import bpy
import numpy as np
from bpy.app.handlers import persistent
from bpy.props import BoolProperty, EnumProperty, IntProperty, StringProperty
from bpy.types import Operator, Panel
from mathutils import Euler, Vector

from ...core.codecs.dense import tabulate
from ...core.codecs.packed import pack
from ...core.codecs.presets import PRESETS, make_preset, preset_parameters
from ...core.errors import BTFError
from ...core.fileio import atomic_write, atomic_write_path
from ...core.formats.container import SUFFIX, write_container
from ...core.formats.image_sets import is_image_set
from ...core.model import BTF
from .. import compat
from ..addon import ENGINE_ID
from ..export.materials import load_cached
from ..paths import absolute, is_btfbase_folder, pack_copy, relative
from .import_btf import display_colour, fill_material, place_on

log = logging.getLogger(__name__)

LIBRARY_BLEND = "btf_materials.blend"
CATALOG_FILE = "blender_assets.cats.txt"  # Blender's name: one per asset library folder
#: Folders inside the library: the presets' .btfm files, copies of the sources.
SYNTHETIC_FOLDER = "synthetic"
COPIES_FOLDER = "sources"
#: Catalog paths by kind of source (Blender shows the parent as a folder).
CATALOG_ROOT = "BTF"
CATALOGS = {
    "btfbase": f"{CATALOG_ROOT}/BTFbase",
    "ubo2014": f"{CATALOG_ROOT}/UBO2014",
    "image_set": f"{CATALOG_ROOT}/Image Sets",
    "btfm": f"{CATALOG_ROOT}/BTF Files",
    "synthetic": f"{CATALOG_ROOT}/Synthetic",
}
#: uuid5 namespace of the catalog ids: a path's id is the same in every build and library.
CATALOG_NAMESPACE = uuid.UUID("6f1d2a47-0b9e-4c55-9a51-3b2f8d7e1c20")
CATALOG_HEADER = (
    "# This is an Asset Catalog Definition file for Blender.\n"
    "#\n"
    "# Empty lines and lines starting with `#` will be ignored.\n"
    "# The first non-ignored line should be the version indicator.\n"
    '# Other lines are of the format "UUID:catalog/path/for/assets:simple catalog name"\n'
    "\n"
    "VERSION 1\n"
    "\n"
)
#: Texels per side of the procedural presets (woven, leather) when tabulated for the library,
#: as the demo scene does: a few seconds each.
PRESET_TEXELS = 8
PRESET_TITLES = {"ggx": "GGX"}
#: How deep the source folder is searched for sources (a folder of BTFbase folders, ...).
SEARCH_DEPTH = 3
#: The preview's swatch spans about this many tiles (real-world size), so a measured BTF shows
#: its structure instead of an average.
PREVIEW_TILES = 4.0


# --- sources ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class LibrarySource:
    """One asset to build: ``path`` absolute; ``preset``: the preset written there first."""

    name: str
    path: Path
    catalog: str
    preset: str = ""


def source_kind(path: Path) -> str:
    """The catalog key (``CATALOGS``) of a BTF source, or '' when ``path`` is none."""
    if path.is_dir():
        if is_btfbase_folder(path) or (path / "binary.btf").is_file():
            return "btfbase"
        return "image_set" if is_image_set(path) else ""
    suffix = path.suffix.lower()
    if suffix == SUFFIX:
        return "btfm"
    if suffix == ".btf" and path.name.lower() != "binary.btf":
        return "ubo2014"
    if suffix == ".zip" and is_image_set(path):
        return "image_set"
    return ""


def find_sources(folder: Path, skip: Path | None = None, depth: int = SEARCH_DEPTH):
    """The BTF sources in ``folder`` and its subfolders (a source folder is not searched
    further), sorted by path; ``skip``: a folder left out (the library's own output)."""
    found = []
    for entry in sorted(folder.iterdir()):
        if entry.name.startswith(".") or (skip is not None and entry == skip):
            continue
        kind = source_kind(entry)
        if kind:
            name = entry.stem if entry.is_file() else entry.name
            found.append(LibrarySource(name, entry, CATALOGS[kind]))
        elif entry.is_dir() and depth > 1:
            found.extend(find_sources(entry, skip, depth - 1))
    return found


def preset_title(name: str) -> str:
    return PRESET_TITLES.get(name, name.title())


def preset_sources(library: Path, names) -> list[LibrarySource]:
    folder = library / SYNTHETIC_FOLDER
    return [
        LibrarySource(preset_title(n), folder / f"{n}{SUFFIX}", CATALOGS["synthetic"], preset=n)
        for n in PRESETS
        if n in names
    ]


def write_preset(name: str, path: Path) -> None:
    """The preset at its defaults as a .btfm; a procedural one (which the GPU back ends cannot
    draw) tabulated on the UBO 81 × 81 grid at ``PRESET_TEXELS`` texels."""
    params = {"texels": PRESET_TEXELS} if "texels" in preset_parameters(name) else {}
    btf = make_preset(name, **params)
    try:
        pack(btf)
    except BTFError:
        btf = tabulate(btf)
    write_container(path, btf)


# --- catalogs ---------------------------------------------------------------------------------
def catalog_uuid(path: str) -> str:
    return str(uuid.uuid5(CATALOG_NAMESPACE, path))


def read_catalogs(file: Path) -> dict[str, str]:
    """Catalog path → id of a ``blender_assets.cats.txt`` ({} when there is none)."""
    catalogs: dict[str, str] = {}
    if not file.is_file():
        return catalogs
    for line in file.read_text(encoding="utf-8").splitlines():
        line = line.strip()
        if not line or line.startswith(("#", "VERSION")):
            continue
        parts = line.split(":")
        if len(parts) >= 2:
            catalogs[parts[1]] = parts[0]
    return catalogs


def write_catalogs(folder: Path, paths) -> dict[str, str]:
    """Add the catalogs ``paths`` (and their parents) to the folder's catalog file, keeping
    every catalog it has (an existing path keeps its id). Returns path → id for ``paths``."""
    file = folder / CATALOG_FILE
    existing = read_catalogs(file)
    wanted = set()
    for path in paths:
        parts = path.split("/")
        wanted.update("/".join(parts[: i + 1]) for i in range(len(parts)))
    added = {p: catalog_uuid(p) for p in sorted(wanted) if p not in existing}
    if added or not file.is_file():
        old = file.read_text(encoding="utf-8") if file.is_file() else CATALOG_HEADER
        lines = "".join(f"{i}:{p}:{p.replace('/', '-')}\n" for p, i in added.items())
        text = (old if old.endswith("\n") else old + "\n") + lines
        atomic_write(file, lambda fh: fh.write(text.encode("utf-8")))
    ids = {**existing, **added}
    return {p: ids[p] for p in paths}


# --- previews ---------------------------------------------------------------------------------
def studio_light() -> Path:
    """Blender's bundled neutral studio environment."""
    return Path(bpy.utils.system_resource("DATAFILES")) / "studiolights" / "world" / "studio.exr"


def _shape_mesh(name: str, shape: str):
    """A unit swatch: a smooth UV sphere of radius 1, or a draped cloth 1.8 wide."""
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")  # UV-mapped materials preview too
    if shape == "CLOTH":
        bmesh.ops.create_grid(bm, x_segments=48, y_segments=48, size=0.9, calc_uvs=True)
        for v in bm.verts:
            x, y = v.co.x, v.co.y
            v.co.z = 0.18 * np.sin(3.4 * x + 0.6) * np.cos(1.2 * y) + 0.08 * np.sin(4.4 * y)
    else:
        bmesh.ops.create_uvsphere(bm, u_segments=48, v_segments=24, radius=1.0, calc_uvs=True)
    bm.to_mesh(mesh)
    bm.free()
    for polygon in mesh.polygons:
        polygon.use_smooth = True
    return mesh


class PreviewStage:
    """A scene of its own for the previews' renders (the user's scenes untouched), rendered by
    this engine's F12 (``bpy.ops.render.render(scene=...)``); ``close`` removes all of it."""

    def __init__(self, size: int = 128, lights: int = 64, shape: str = "SPHERE"):
        self.size, self.shape = size, shape
        self._render_result = "Render Result" in bpy.data.images
        self._folder = tempfile.TemporaryDirectory(prefix="btf-previews-")
        self.scene = scene = bpy.data.scenes.new("BTF Library Preview")
        scene.render.engine = ENGINE_ID
        scene.render.resolution_x = scene.render.resolution_y = size
        scene.render.resolution_percentage = 100
        scene.render.film_transparent = True  # the Asset Browser shows the swatch alone
        scene.render.dither_intensity = 0.0
        scene.render.image_settings.file_format = "PNG"
        scene.render.image_settings.color_mode = "RGBA"
        scene.render.image_settings.color_depth = "8"
        # Preview pixels are display bytes: the plain sRGB curve, as Blender's own previews.
        scene.view_settings.view_transform = "Standard"
        scene.view_settings.look = "None"
        settings = scene.btf_render
        settings.final_mode = "VIRTUAL"  # deterministic, no noise at a few lights
        settings.lighting = "ENVIRONMENT"
        settings.lights_total = lights
        self.mesh = _shape_mesh("BTF Library Preview", shape)
        self.mesh.materials.append(None)
        self.object = bpy.data.objects.new("BTF Library Preview", self.mesh)
        scene.collection.objects.link(self.object)
        self.camera = bpy.data.objects.new("BTF Library Preview", bpy.data.cameras.new("BTF"))
        scene.collection.objects.link(self.camera)
        scene.camera = self.camera
        self.world = compat.with_nodes(bpy.data.worlds.new("BTF Library Preview"))
        self.image = None
        nodes = self.world.node_tree.nodes
        if studio_light().is_file():
            texture = nodes.new("ShaderNodeTexEnvironment")
            self.image = texture.image = bpy.data.images.load(str(studio_light()))
            self.world.node_tree.links.new(
                texture.outputs["Color"], nodes["Background"].inputs["Color"]
            )
        else:  # a neutral grey
            nodes["Background"].inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
        scene.world = self.world

    def _place(self, scale: float) -> None:
        """The swatch at ``scale`` (radius in scene units) and the camera framing it. The
        originals' matrices are set here: nothing evaluates this scene's originals, and F12
        reads the camera's (blender/export/camera.py)."""
        # The cloth turned to face the camera, a little from above.
        rotation = Euler((np.radians(62.0), 0.0, 0.0)) if self.shape == "CLOTH" else Euler()
        self.object.location, self.object.rotation_euler = (0.0, 0.0, 0.0), rotation
        self.object.scale = (scale, scale, scale)
        self.camera.location = Vector((0.0, -3.6 * scale, 1.2 * scale))
        self.camera.rotation_euler = Euler((np.radians(72.0), 0.0, 0.0))
        for obj in (self.object, self.camera):
            obj.matrix_world = obj.matrix_basis  # no parents
        self.camera.data.clip_start = 0.01 * scale
        self.camera.data.clip_end = 100.0 * scale

    def render(self, material, scale: float = 1.0) -> np.ndarray:
        """``material`` on the swatch → (size, size, 4) float32 display RGBA in [0, 1], bottom
        row first (Blender's and its previews' order). Raises RuntimeError with F12's report
        when the render fails."""
        self.mesh.materials[0] = material
        self._place(scale)
        path = os.path.join(self._folder.name, "preview.png")
        self.scene.render.filepath = path
        if os.path.exists(path):
            os.remove(path)
        bpy.ops.render.render(write_still=True, scene=self.scene.name)
        if not os.path.exists(path):
            raise RuntimeError("the preview render wrote no image")
        image = bpy.data.images.load(path, check_existing=False)
        try:
            w, h = image.size
            pixels = np.empty(w * h * 4, dtype=np.float32)
            image.pixels.foreach_get(pixels)  # a byte image: its bytes / 255, not linearised
        finally:
            bpy.data.images.remove(image)
        return pixels.reshape(h, w, 4)

    def close(self) -> None:
        scene, camera_data = self.scene, self.camera.data
        bpy.data.objects.remove(self.object)
        bpy.data.objects.remove(self.camera)
        bpy.data.cameras.remove(camera_data)
        bpy.data.meshes.remove(self.mesh)
        bpy.data.scenes.remove(scene)
        bpy.data.worlds.remove(self.world)
        if self.image is not None:
            bpy.data.images.remove(self.image)
        result = bpy.data.images.get("Render Result")
        if result is not None and not self._render_result:  # made by these renders
            bpy.data.images.remove(result)
        self._folder.cleanup()


def preview_scale(settings, btf: BTF) -> float:
    """Swatch radius in scene units: ``PREVIEW_TILES`` real-world tiles across (Box or UV at
    real-world size), else 2 (one tile per unit or per UV square)."""
    if settings.use_real_world_size:
        size = tuple(settings.tile_size_mm)
        tile = size if min(size) > 0.0 else btf.meta.tile_size_mm
        if tile is not None:
            return PREVIEW_TILES * max(tile) / 1000.0 / 2.0
    return 2.0


def store_preview(block, pixels: np.ndarray) -> None:
    """``pixels`` ((h, w, 4) float display RGBA, bottom row first) as the preview of the ID
    ``block``: its image, and its icon (32 × 32, nearest texels)."""
    preview = block.preview_ensure()
    h, w = pixels.shape[:2]
    preview.image_size = (w, h)
    preview.image_pixels_float.foreach_set(np.ascontiguousarray(pixels, np.float32).ravel())
    icon = 32
    rows = (np.arange(icon) * h) // icon
    cols = (np.arange(icon) * w) // icon
    preview.icon_size = (icon, icon)
    preview.icon_pixels_float.foreach_set(np.ascontiguousarray(pixels[rows][:, cols]).ravel())


def settings_values(settings) -> dict:
    """A material's ``btf`` settings as plain values (to copy onto another material)."""
    values = {}
    for prop in settings.bl_rna.properties:
        if prop.identifier == "rna_type" or prop.is_readonly:
            continue
        value = getattr(settings, prop.identifier)
        values[prop.identifier] = (
            tuple(value) if hasattr(value, "__len__") and not isinstance(value, str) else value
        )
    return values


# --- the build --------------------------------------------------------------------------------
@dataclass
class Asset:
    """One built asset, held as plain values until the library is written."""

    name: str
    source: str  # absolute
    catalog: str
    settings: dict
    colour: tuple
    preview: np.ndarray
    description: str
    tags: tuple[str, ...]


def describe(name: str, btf: BTF, settings) -> tuple[str, tuple[str, ...]]:
    meta = btf.meta
    size = tuple(settings.tile_size_mm)
    tile = size if min(size) > 0.0 else meta.tile_size_mm
    text = f"{name}: {meta.codec} BTF, {meta.width}×{meta.height} texels"
    if tile is not None:
        assumed = " (assumed)" if settings.tile_size_origin == "ASSUMED" else ""
        text += f", tile {tile[0]:g}×{tile[1]:g} mm{assumed}"
    return text, (CATALOG_ROOT, meta.codec)


class LibraryBuild:
    """The build, one source per ``step()`` (the modal operator runs one per timer tick),
    then ``write()``. Failures are collected, never raised."""

    def __init__(self, library: Path, blend_name: str, sources, copy_sources: bool, stage):
        self.library, self.blend = library, library / blend_name
        self.sources, self.copy_sources, self.stage = list(sources), copy_sources, stage
        self.assets: list[Asset] = []
        self.failures: list[tuple[str, str]] = []  # (source, why)
        self.next = 0

    @property
    def done(self) -> bool:
        return self.next >= len(self.sources)

    def step(self) -> None:
        source = self.sources[self.next]
        self.next += 1
        try:
            self.assets.append(self._build(source))
        except (BTFError, OSError, ValueError, RuntimeError) as exc:
            log.warning("library source %s failed: %s", source.path, exc)
            self.failures.append((str(source.path), str(exc)))

    def _build(self, source: LibrarySource) -> Asset:
        path = source.path
        if source.preset:
            write_preset(source.preset, path)
        elif self.copy_sources and not path.is_relative_to(self.library):
            copy = self.library / COPIES_FOLDER / path.name
            pack_copy(path, copy)
            path = copy
        btf = load_cached(str(path))
        pack(btf)  # the GPU back ends must draw it: refused here, as Import refuses it
        material = compat.with_nodes(bpy.data.materials.new(f"BTF preview {source.name}"))
        try:
            fill_material(material, str(path), btf)
            place_on(material, btf, [])  # no target: Box mapping, fits any mesh
            preview = self.stage.render(material, preview_scale(material.btf, btf))
            values = settings_values(material.btf)
            description, tags = describe(source.name, btf, material.btf)
        finally:
            bpy.data.materials.remove(material)
        leaf = source.catalog.rsplit("/", 1)[-1]
        tags = tuple(dict.fromkeys((*tags, leaf)))
        colour = display_colour(btf)
        return Asset(
            source.name, str(path), source.catalog, values, colour, preview, description, tags
        )

    def write(self) -> Path:
        """The assets into the library .blend (replacing it whole) and the catalogs file."""
        ids = write_catalogs(self.library, sorted({a.catalog for a in self.assets}))
        blend = str(self.blend)
        with bpy.data.temp_data() as data:
            materials = {
                self._material(data, asset, ids[asset.catalog], blend) for asset in self.assets
            }
            atomic_write_path(
                self.blend, lambda tmp: data.libraries.write(str(tmp), materials, fake_user=True)
            )
        return self.blend

    @staticmethod
    def _material(data, asset: Asset, catalog_id: str, blend: str):
        material = compat.with_nodes(data.materials.new(asset.name))
        for name, value in asset.settings.items():
            setattr(material.btf, name, value)
        material.btf.source = relative(asset.source, blend)  # the library moves as a whole
        material.diffuse_color = asset.colour
        if material.node_tree is not None:  # other engines show the mean colour
            principled = material.node_tree.nodes.get("Principled BSDF")
            if principled is not None:
                principled.inputs["Base Color"].default_value = asset.colour
        material.asset_mark()
        material.asset_data.description = asset.description
        for tag in asset.tags:
            material.asset_data.tags.new(tag, skip_if_exists=True)
        material.asset_data.catalog_id = catalog_id
        store_preview(material, asset.preview)
        return material


def register_asset_library(name: str, folder: Path):
    """The folder as a user asset library (Preferences › File Paths), appending its assets;
    an entry for the same folder is reused (renamed)."""
    libraries = bpy.context.preferences.filepaths.asset_libraries
    target = os.path.normcase(os.path.normpath(str(folder)))
    for library in libraries:
        if os.path.normcase(os.path.normpath(bpy.path.abspath(library.path))) == target:
            break
    else:
        library = libraries.new(name=name, directory=str(folder))
    library.name = name
    # Append (reusing what was appended before where Blender offers it): a BTF material in a
    # shot should not change when the library is rebuilt.
    try:
        library.import_method = "APPEND_REUSE"  # Blender 4.x
    except TypeError:  # 5.0 lists LINK, APPEND (reusing), PACK
        library.import_method = "APPEND"
    return library


#: The presets as ENUM_FLAG items (numbers: one bit each) and the default (all of them).
PRESET_ITEMS = [
    (name.upper(), preset_title(name), f"The {name} preset", 1 << i)
    for i, name in enumerate(PRESETS)
]
ALL_PRESETS = {name.upper() for name in PRESETS}


class BTF_OT_build_asset_library(Operator):
    """Build an asset library from a folder of BTF sources and the synthetic presets: one
    material asset each, with a preview rendered by this engine, in catalogs"""

    bl_idname = "btf.build_asset_library"
    bl_label = "Build BTF Material Library"
    # Writes files only: the open file keeps nothing of the build, so there is nothing to undo.
    bl_options = {"REGISTER"}

    directory: StringProperty(
        name="Library Folder",
        subtype="DIR_PATH",
        description="Folder the library .blend, its catalogs and the presets' files go into",
    )
    source_folder: StringProperty(
        name="BTF Sources",
        subtype="DIR_PATH",
        description="Folder searched for BTF sources (BTFbase folders, .btfm, UBO2014 .btf, "
        "image sets), subfolders too; empty: the presets only",
    )
    presets: EnumProperty(
        name="Presets",
        items=PRESET_ITEMS,
        options={"ENUM_FLAG"},
        default=ALL_PRESETS,
        description="Synthetic presets added to the library (written as .btfm files into its "
        "synthetic folder)",
    )
    copy_sources: BoolProperty(
        name="Copy Sources",
        default=False,
        description="Copy each source into the library's sources folder, so the library "
        "folder alone can be moved or shared; off: sources stay where they are, stored "
        "relative to the library (move both together)",
    )
    shape: EnumProperty(
        name="Preview Shape",
        items=(("SPHERE", "Sphere", "A sphere", 0), ("CLOTH", "Cloth", "A draped cloth", 1)),
        default="SPHERE",
    )
    preview_size: IntProperty(name="Preview Size", default=128, min=16, max=512)
    preview_lights: IntProperty(
        name="Preview Lights",
        default=64,
        min=1,
        max=4096,
        description="Virtual lights of each preview render (more: smoother highlights)",
    )
    blend_name: StringProperty(name="Library File", default=LIBRARY_BLEND)
    register_library: BoolProperty(
        name="Add to Preferences",
        default=False,
        description="Register the folder as an asset library in Preferences › File Paths",
    )
    library_name: StringProperty(name="Library Name", default="BTF Materials")

    _build: LibraryBuild | None = None
    _timer = None

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=420)

    def _start(self) -> LibraryBuild | None:
        if not self.directory:
            self.report({"ERROR"}, "no library folder given")
            return None
        library = Path(bpy.path.abspath(self.directory)).resolve()
        if library.exists() and not library.is_dir():
            self.report({"ERROR"}, f"{library} is not a folder")
            return None
        if not self.blend_name.endswith(".blend") or os.sep in self.blend_name:
            self.report({"ERROR"}, f"library file {self.blend_name!r}: a .blend name expected")
            return None
        sources = []
        if self.source_folder:
            folder = Path(bpy.path.abspath(self.source_folder)).resolve()
            if not folder.is_dir():
                self.report({"ERROR"}, f"{folder}: no such folder")
                return None
            # The library's own output is not a source: inside the sources, all of it.
            skip = library / SYNTHETIC_FOLDER if library == folder else library
            sources = find_sources(folder, skip)
        sources += preset_sources(library, {p.lower() for p in self.presets})
        if not sources:
            self.report({"ERROR"}, "no BTF sources found and no presets chosen")
            return None
        library.mkdir(parents=True, exist_ok=True)
        stage = PreviewStage(self.preview_size, self.preview_lights, self.shape)
        return LibraryBuild(library, self.blend_name, sources, self.copy_sources, stage)

    def execute(self, context):
        build = self._start()
        if build is None:
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, len(build.sources))
        window = getattr(context, "window", None)
        if window is not None and not bpy.app.background:
            self._build = build
            self._timer = wm.event_timer_add(0.05, window=window)
            wm.modal_handler_add(self)
            self.report({"INFO"}, f"building {len(build.sources)} assets… (Esc cancels)")
            return {"RUNNING_MODAL"}
        try:
            while not build.done:
                build.step()
                wm.progress_update(build.next)
        finally:
            build.stage.close()
            wm.progress_end()
        return self._finish(context, build)

    def modal(self, context, event):
        build = self._build
        if event.type == "ESC":
            self._end(context)
            self.report({"WARNING"}, "library build cancelled; nothing written")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        name = build.sources[build.next].name
        context.workspace.status_text_set(
            f"BTF library: {build.next + 1}/{len(build.sources)} {name} (Esc cancels)"
        )
        try:
            build.step()
        except Exception:  # a bug: the timer, the bar and the stage go before it shows
            self._end(context)
            raise
        context.window_manager.progress_update(build.next)
        if not build.done:
            return {"RUNNING_MODAL"}
        self._end(context)
        return self._finish(context, build)

    def _end(self, context) -> None:
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        context.workspace.status_text_set(None)
        self._build.stage.close()

    def _finish(self, context, build: LibraryBuild) -> set[str]:
        # The loaders' messages name their file; others get it in front.
        failed = [why if source in why else f"{source}: {why}" for source, why in build.failures]
        for line in failed:
            self.report({"WARNING"}, f"not added to the library: {line}")
        if not build.assets:
            self.report({"ERROR"}, "no asset could be built: " + "; ".join(failed))
            return {"CANCELLED"}
        try:
            blend = build.write()
        except (OSError, RuntimeError) as exc:
            self.report({"ERROR"}, f"library not written: {exc}")
            return {"CANCELLED"}
        note = ""
        if self.register_library:
            library = register_asset_library(self.library_name, build.library)
            note = f"; asset library {library.name!r} added to the Preferences"
        failures = f", {len(failed)} failed (see the warnings)" if failed else ""
        self.report({"INFO"}, f"{blend}: {len(build.assets)} BTF assets{failures}{note}")
        return {"FINISHED"}


class BTF_OT_render_preview(Operator):
    """Render the material's preview with the BTF engine (as F12 renders it) and store it: what
    the Asset Browser shows once the material is marked as an asset"""

    bl_idname = "btf.render_preview"
    bl_label = "Render BTF Preview"
    bl_options = {"REGISTER", "UNDO"}

    material: StringProperty(name="Material", options={"SKIP_SAVE"})
    shape: EnumProperty(
        name="Preview Shape",
        items=(("SPHERE", "Sphere", "A sphere", 0), ("CLOTH", "Cloth", "A draped cloth", 1)),
        default="SPHERE",
    )
    size: IntProperty(name="Size", default=128, min=16, max=512)

    @classmethod
    def poll(cls, context) -> bool:
        material = getattr(context, "material", None)
        return material is None or material.library is None

    def execute(self, context):
        material = (
            bpy.data.materials.get(self.material)
            if self.material
            else getattr(context, "material", None)
        )
        if material is None:
            self.report({"ERROR"}, "no material to preview")
            return {"CANCELLED"}
        btf = None
        if material.btf.enabled and material.btf.source:
            try:
                btf = load_cached(material.btf.source)
            except (BTFError, OSError) as exc:
                self.report({"ERROR"}, f"material {material.name!r}: {exc}")
                return {"CANCELLED"}
        stage = PreviewStage(self.size, shape=self.shape)
        try:
            scale = preview_scale(material.btf, btf) if btf is not None else 1.0
            pixels = stage.render(material, scale)
        except RuntimeError as exc:
            self.report({"ERROR"}, f"preview of {material.name!r} failed: {exc}")
            return {"CANCELLED"}
        finally:
            stage.close()
        store_preview(material, pixels)
        self.report({"INFO"}, f"preview of {material.name!r} rendered with the BTF engine")
        return {"FINISHED"}


# --- applying assets: sources rebased onto the user's file --------------------------------------
def source_from_library(source: str, library) -> str:
    """A "//" source of a material from ``library`` as an absolute path."""
    return os.path.normpath(bpy.path.abspath(source, library=library))


def rebased_source(source: str, library) -> str:
    """Where an appended material's "//" source (relative to ``library``'s file) points, as
    this file writes paths: relative when it is saved and relative paths are the default."""
    found = source_from_library(source, library)
    if bpy.data.filepath and bpy.context.preferences.filepaths.use_relative_paths:
        return relative(found, bpy.data.filepath)
    return absolute(found, bpy.data.filepath)


def _btf_source(material) -> str:
    settings = getattr(material, "btf", None)
    return settings.source if settings is not None else ""


# Local materials before an import (pointers): the ones after it that are new were appended,
# directly or as what an appended object or node tree uses.
_before_import: set[int] = set()


@persistent
def note_local_materials(_import_context) -> None:
    """blend_import_pre: remember the local materials."""
    _before_import.clear()
    _before_import.update(m.as_pointer() for m in bpy.data.materials if m.library is None)


@persistent
def rebase_imported_sources(import_context) -> None:
    """blend_import_post: the "//" sources of appended BTF materials rebased from their library
    onto this file (an append reads from one library; reused materials are not new); linked
    ones resolved against their library (in memory: this file does not store linked data)."""
    libraries = {
        item.source_library.filepath: item.source_library
        for item in import_context.import_items
        if item.source_library is not None
    }
    if len(libraries) == 1:
        (library,) = libraries.values()
        for material in bpy.data.materials:
            if (
                material.library is None
                and material.as_pointer() not in _before_import
                and _btf_source(material).startswith("//")
            ):
                material.btf.source = rebased_source(material.btf.source, library)
    _before_import.clear()
    resolve_linked_sources()


@persistent
def resolve_linked_sources(*_args) -> None:
    """load_post (and after an import): linked BTF materials come with their library's "//"
    sources; each gets the absolute path, in memory."""
    for material in bpy.data.materials:
        if material.library is not None and _btf_source(material).startswith("//"):
            material.btf.source = source_from_library(material.btf.source, material.library)


def menu_export(self, context) -> None:
    label = f"{BTF_OT_build_asset_library.bl_label}…"  # a dialog opens
    self.layout.operator(BTF_OT_build_asset_library.bl_idname, text=label)


class BTF_PT_material_asset_preview(Panel):
    """Material Properties › BTF › Asset Preview: the preview the Asset Browser shows."""

    bl_label = "Asset Preview"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"
    bl_parent_id = "BTF_PT_material"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context) -> bool:
        material = context.material
        return (
            context.engine == ENGINE_ID
            and material is not None
            and material.library is None
            and material.btf.enabled
        )

    def draw(self, context) -> None:
        op = self.layout.operator(BTF_OT_render_preview.bl_idname, icon="RENDER_STILL")
        op.material = context.material.name


classes = (BTF_OT_build_asset_library, BTF_OT_render_preview, BTF_PT_material_asset_preview)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def _import_handlers():
    """(handlers, function) pairs: blend_import_pre/post exist from Blender 4.3 on."""
    pairs = (
        ("blend_import_pre", note_local_materials),
        ("blend_import_post", rebase_imported_sources),
    )
    return [(getattr(bpy.app.handlers, n), f) for n, f in pairs if hasattr(bpy.app.handlers, n)]


def register() -> None:
    _register()
    bpy.types.TOPBAR_MT_file_export.append(menu_export)
    for handlers, function in _import_handlers():
        handlers.append(function)
    bpy.app.handlers.load_post.append(resolve_linked_sources)


def unregister() -> None:
    bpy.app.handlers.load_post.remove(resolve_linked_sources)
    for handlers, function in reversed(_import_handlers()):
        handlers.remove(function)
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    _unregister()

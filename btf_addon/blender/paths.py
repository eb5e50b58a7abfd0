"""BTF sources behave like image paths: farm-safe relative paths, File › External Data. A
scene's light bake (``scene.btf_bake.path``, blender/bake/) is external data of the same kind
and gets the same treatment, save remap and the four operators alike (``external_paths``).

Blender's own Make Paths Relative, Pack Resources and Report Missing Files are C operators that
know only Blender's file types, with no Python hook; so this module gives BTF sources
(``material.btf.source``: a BTFbase folder or a ``.btfm`` file) the same treatment:

- a ``save_pre`` handler remaps sources as Blender remaps image paths on save: a relative
  source keeps pointing at the same data when the .blend is saved elsewhere, and an absolute
  one becomes relative when the file is saved for the first time (with the Preferences' File
  Paths › Default Relative Paths on, Blender's default); ``save_post`` undoes the remap in the
  open session after Save Copy, whose saved file lives elsewhere;
- operators in File › External Data: Make BTF Paths Relative / Absolute, Report Missing BTF
  Sources, Pack BTF Sources beside the .blend (copied into a ``btf_sources`` folder next to it,
  paths made relative: the .blend and that folder render anywhere together);
- F12's check for sources that cannot be loaded (``missing_sources``): the render fails naming
  them, or, by the preference, renders them in Cycles' missing-texture magenta.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import bpy
from bpy.app.handlers import persistent
from bpy.types import Operator

from ..core.codecs.analytic import LambertianBTF
from ..core.errors import BTFError
from .export.materials import load_cached

#: Folder beside the .blend that Pack BTF Sources copies sources into.
PACK_FOLDER = "btf_sources"
#: Cycles' missing-texture colour (magenta), as an albedo.
ERROR_ALBEDO = (1.0, 0.0, 1.0)


def btf_materials():
    """The local materials (not linked from a library) that render from a BTF source."""
    return [
        m
        for m in bpy.data.materials
        if m.library is None and getattr(m, "btf", None) is not None and m.btf.source
    ]


class ExternalPath(NamedTuple):
    """One path to external data: ``holder.attribute`` (a material's ``btf.source``, a
    scene's ``btf_bake.path``), ``label`` names its owner in reports and ``key`` is unique."""

    holder: object
    attribute: str
    label: str
    key: tuple[str, str]

    @property
    def value(self) -> str:
        return getattr(self.holder, self.attribute)

    @value.setter
    def value(self, new: str) -> None:
        setattr(self.holder, self.attribute, new)


def external_paths() -> list[ExternalPath]:
    """Every local BTF source, then every local scene's light bake."""
    paths = [
        ExternalPath(m.btf, "source", f"material {m.name!r}", ("material", m.name))
        for m in btf_materials()
    ]
    for scene in bpy.data.scenes:
        bake = getattr(scene, "btf_bake", None)
        if scene.library is None and bake is not None and bake.path:
            paths.append(
                ExternalPath(
                    bake, "path", f"scene {scene.name!r} light bake", ("scene", scene.name)
                )
            )
    return paths


def _holder(key: tuple[str, str]):
    """The holder of a path by its key, None where its owner is gone."""
    kind, name = key
    if kind == "material":
        material = bpy.data.materials.get(name)
        return material.btf if material is not None else None
    scene = bpy.data.scenes.get(name)
    return scene.btf_bake if scene is not None else None


def absolute(source: str, blend_path: str) -> str:
    """``source`` as an absolute, normalised path; a "//" path is taken relative to the folder
    of ``blend_path`` (unchanged when there is none: nothing to resolve it against)."""
    if source.startswith("//"):
        if not blend_path:
            return source
        return os.path.normpath(os.path.join(os.path.dirname(blend_path), source[2:]))
    return os.path.normpath(os.path.abspath(source))


def relative(source_abs: str, blend_path: str) -> str:
    """``source_abs`` as a "//" path relative to ``blend_path``'s folder, or unchanged where
    none exists (another drive on Windows)."""
    try:
        rel = os.path.relpath(source_abs, os.path.dirname(blend_path))
    except ValueError:
        return source_abs
    return "//" + rel.replace(os.sep, "/")


def remapped(source: str, old_blend: str, new_blend: str, make_relative: bool) -> str:
    """Where a source points after the .blend moves from ``old_blend`` ('' = never saved) to
    ``new_blend``: relative stays relative (to the same data), absolute becomes relative on the
    first save when ``make_relative``, else stays absolute."""
    if source.startswith("//"):
        if not old_blend:
            return source  # relative to nothing yet: leave as the user wrote it
        return relative(absolute(source, old_blend), new_blend)
    if not old_blend and make_relative:
        return relative(absolute(source, ""), new_blend)
    return source


# Save Copy writes a file elsewhere but leaves this session's file where it was: the paths
# remapped for the copy are restored after it is written (by ExternalPath.key: the attribute
# and the value it had).
_before_save: dict[tuple[str, str], tuple[str, str]] = {}


@persistent
def remap_on_save(filepath: str, *_args) -> None:
    """save_pre: remap BTF sources and light bakes for the file about to be written at
    ``filepath``."""
    _before_save.clear()
    if not filepath:
        return  # the startup file
    make_relative = bpy.context.preferences.filepaths.use_relative_paths
    for path in external_paths():
        old = path.value
        new = remapped(old, bpy.data.filepath, filepath, make_relative)
        if new != old:
            _before_save[path.key] = (path.attribute, old)
            path.value = new


@persistent
def restore_after_copy(filepath: str, *_args) -> None:
    """save_post: after Save Copy (the session's file did not move), put the paths back."""
    if filepath and os.path.normpath(bpy.data.filepath) != os.path.normpath(filepath):
        for key, (attribute, old) in _before_save.items():
            holder = _holder(key)
            if holder is not None:
                setattr(holder, attribute, old)
    _before_save.clear()


class MissingSource(NamedTuple):
    material: str
    source: str
    reason: str


def source_problem(source: str, prefer_binary: bool = False) -> str:
    """Why ``source`` cannot be rendered, or '' when it loads."""
    if not source:
        return "BTF enabled but no source set"
    try:
        load_cached(source, prefer_binary)  # cached: free when F12's export has just loaded it
    except (BTFError, OSError, ValueError) as exc:
        return str(exc)
    return ""


def missing_sources(exported) -> list[MissingSource]:
    """The BTF materials of an exported scene whose source cannot be loaded (F12 checks this:
    the export itself falls back to the material's surface, which suits the viewport)."""
    missing = []
    for render_material in exported.materials:
        material = bpy.data.materials.get(render_material.name)
        settings = getattr(material, "btf", None)
        if settings is None or not settings.enabled:
            continue
        problem = source_problem(settings.source, settings.prefer_binary)
        if problem:
            missing.append(MissingSource(material.name, settings.source, problem))
    return missing


def missing_message(missing: list[MissingSource]) -> str:
    """F12's refusal: one line for one source (what a farm's log shows first), naming the
    material and the file; a line per source after a heading for several."""
    advice = (
        "File › External Data › Report Missing BTF Sources lists them; the add-on's "
        "preferences can render them magenta instead."
    )

    def line(m: MissingSource) -> str:
        named = m.reason if not m.source or m.source in m.reason else f"{m.source}: {m.reason}"
        return f"material {m.material!r}: {named}"

    if len(missing) == 1:
        return f"BTF source missing; nothing rendered: {line(missing[0])}. {advice}"
    lines = "\n".join(line(m) for m in missing)
    return f"{len(missing)} BTF sources missing; nothing rendered:\n{lines}\n{advice}"


def with_error_colour(exported, missing: list[MissingSource]):
    """``exported`` with each missing material rendered magenta (Cycles' missing texture)."""
    names = {m.material for m in missing}
    for i, material in enumerate(exported.materials):
        if material.name in names:
            exported.materials[i] = replace(material, btf=LambertianBTF(ERROR_ALBEDO), exposure=0)
    exported.messages.extend(
        f"material {m.material!r} rendered magenta: {m.reason}" for m in missing
    )
    return exported


#: The file that marks a BTFbase material folder.
BTFBASE_MARKER = "all_materialInfo.txt"
#: Files that are a BTF source on their own (not a table of a folder).
SINGLE_FILE_SUFFIXES = (".btfm",)
#: An image inside an image-set folder stands for the folder (core/formats/image_sets.py).
IMAGE_SET_SUFFIXES = (".jpg", ".jpeg", ".hdr")


def is_btfbase_folder(folder: Path) -> bool:
    return (folder / BTFBASE_MARKER).is_file()


def source_for(filepath: str) -> str:
    """The BTF source a chosen path stands for, in the same form (a "//" path stays relative):
    a folder or a ``.btfm`` file is itself; any file inside a BTFbase material folder (a text
    table, ``binary.btf``) or an image of an image set stands for the folder; another file is
    itself (UBO2014 ``.btf``, an image-set ``.zip``, or an error ``load_btf`` will name)."""
    if not filepath:
        return ""
    stripped = filepath.rstrip("/\\") or filepath
    resolved = Path(bpy.path.abspath(stripped))
    if resolved.is_dir() or resolved.suffix.lower() in SINGLE_FILE_SUFFIXES:
        return stripped
    if is_btfbase_folder(resolved.parent) or resolved.name.lower() == "binary.btf":
        return os.path.dirname(stripped)
    if resolved.suffix.lower() in IMAGE_SET_SUFFIXES:  # one image of a UBO2003/ATRIUM set
        return os.path.dirname(stripped)
    return stripped  # UBO2014 .btf, an image-set .zip, or an error load_btf will name


def source_hint(filepath: str) -> str:
    """What is wrong with a chosen path, in the file browser's words, or '' when it can be
    loaded (as far as a glance tells: ``load_btf`` checks the rest)."""
    if not filepath:
        return (
            "no BTF chosen: pick a BTFbase material folder (the one holding "
            f"{BTFBASE_MARKER}) or a .btfm file"
        )
    source = Path(bpy.path.abspath(source_for(filepath)))
    if not source.exists():
        return f"{source}: no such file or folder"
    if source.is_file() and source.suffix.lower() in (".txt", ".dat"):
        return (
            f"{source.name} is not a BTF on its own: pick the material's folder (the one holding "
            f"{BTFBASE_MARKER} and the <material>_PDF6D tables) or a .btfm file"
        )
    return ""


def _require_saved(operator) -> bool:
    if not bpy.data.filepath:
        operator.report({"ERROR"}, "save the .blend first: paths are relative to its folder")
        return False
    return True


def _remap_sources(operator, made: str, remap) -> set[str]:
    """Every BTF source and light bake through ``remap(path, blend path)``; reports how many
    changed."""
    if not _require_saved(operator):
        return {"CANCELLED"}
    changed = 0
    for path in external_paths():
        new = remap(path.value, bpy.data.filepath)
        if new != path.value:
            path.value, changed = new, changed + 1
    operator.report({"INFO"}, f"{changed} BTF path(s) made {made}")
    return {"FINISHED"}


class BTF_OT_make_paths_relative(Operator):
    """Make every BTF source relative to the .blend (as Make Paths Relative does for images)"""

    bl_idname = "btf.make_paths_relative"
    bl_label = "Make BTF Paths Relative"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        return _remap_sources(
            self, "relative", lambda src, blend: relative(absolute(src, blend), blend)
        )


class BTF_OT_make_paths_absolute(Operator):
    """Make every BTF source an absolute path"""

    bl_idname = "btf.make_paths_absolute"
    bl_label = "Make BTF Paths Absolute"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        return _remap_sources(self, "absolute", absolute)


class BTF_OT_report_missing(Operator):
    """Report BTF materials whose source cannot be loaded"""

    bl_idname = "btf.report_missing"
    bl_label = "Report Missing BTF Sources"

    def execute(self, context):
        missing = 0
        for material in btf_materials():
            if not material.btf.enabled:
                continue
            problem = source_problem(material.btf.source, material.btf.prefer_binary)
            if problem:
                missing += 1
                self.report({"WARNING"}, f"material {material.name!r}: {problem}")
        bakes = [p for p in external_paths() if p.key[0] == "scene"]
        for path in bakes:  # not fatal (objects are lit live), but a farm should know
            if not os.path.isfile(absolute(path.value, bpy.data.filepath)):
                missing += 1
                self.report({"WARNING"}, f"{path.label}: {path.value} is missing; bake again")
        self.report({"INFO"}, f"{missing} BTF source(s) or light bake(s) missing")
        return {"FINISHED"}


class BTF_OT_pack_beside(Operator):
    """Copy every BTF source and light bake into a btf_sources folder beside the .blend and
    point the materials and scenes there (relative): the .blend and that folder render on any
    machine"""

    bl_idname = "btf.pack_beside"
    bl_label = "Pack BTF Sources beside the .blend"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        if not _require_saved(self):
            return {"CANCELLED"}
        folder = Path(bpy.data.filepath).parent / PACK_FOLDER
        copied: dict[str, str] = {}  # absolute source → its copy, so shared sources copy once
        for path in external_paths():
            source = absolute(path.value, bpy.data.filepath)
            if source not in copied:
                if not os.path.exists(source):
                    self.report({"WARNING"}, f"{path.label}: {source} is missing")
                    continue
                target = folder / Path(source).name
                if Path(source) != target:
                    pack_copy(Path(source), target)
                copied[source] = str(target)
            path.value = relative(copied[source], bpy.data.filepath)
        self.report({"INFO"}, f"{len(copied)} BTF source(s) and light bake(s) packed into {folder}")
        return {"FINISHED"}


def pack_copy(source: Path, target: Path) -> None:
    """Copy a .btfm file or a BTFbase folder to ``target`` (replacing an older copy)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    if source.is_dir():
        shutil.copytree(source, target, dirs_exist_ok=True)
    else:
        shutil.copy2(source, target)


def menu_external_data(self, context) -> None:
    layout = self.layout
    layout.separator()
    layout.operator(BTF_OT_make_paths_relative.bl_idname)
    layout.operator(BTF_OT_make_paths_absolute.bl_idname)
    layout.operator(BTF_OT_report_missing.bl_idname)
    layout.operator(BTF_OT_pack_beside.bl_idname)


classes = (
    BTF_OT_make_paths_relative,
    BTF_OT_make_paths_absolute,
    BTF_OT_report_missing,
    BTF_OT_pack_beside,
)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register() -> None:
    _register()
    bpy.types.TOPBAR_MT_file_external_data.append(menu_external_data)
    bpy.app.handlers.save_pre.append(remap_on_save)
    bpy.app.handlers.save_post.append(restore_after_copy)


def unregister() -> None:
    bpy.app.handlers.save_post.remove(restore_after_copy)
    bpy.app.handlers.save_pre.remove(remap_on_save)
    bpy.types.TOPBAR_MT_file_external_data.remove(menu_external_data)
    _unregister()

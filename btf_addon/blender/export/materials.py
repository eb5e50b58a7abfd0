"""Blender materials → render materials: the BTF a material's ``btf`` settings name, else an
analytic BTF of its surface shader (``surface_shaders.py``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import bpy

from ...core.errors import BTFError
from ...core.formats.load import load_btf, load_warnings
from ...core.model import BTF
from ...scene.scene import Material
from .surface_shaders import analytic_btf

#: The material an empty slot (or an object without slots) renders with.
DEFAULT_MATERIAL_NAME = "default"
#: What a Box-mapped material asks of meshes instead of a UV map name: UVs optional (the UV
#: pass still shows the active render map where there is one), no warning without one.
BOX_MAPPED = "\x00box"


@dataclass(frozen=True)
class BTFFileKey:
    """A BTF source on disk as it was when loaded: a rewritten file has a new mtime."""

    path: str  # absolute, resolved
    mtime: float  # -1.0 when the path does not exist (loading it raises)
    binary: bool = False  # a BTFbase folder read from its binary.btf alone (the user's choice)


# Loading a BTF is costly (text tables, checksums): keep each by path and modification time.
_btf_cache: dict[BTFFileKey, BTF] = {}


def file_key(path: str, prefer_binary: bool = False) -> BTFFileKey:
    """``path`` (Blender's "//" relative paths allowed) as it is on disk now."""
    resolved = Path(bpy.path.abspath(path)).resolve()
    mtime = resolved.stat().st_mtime if resolved.exists() else -1.0
    return BTFFileKey(str(resolved), mtime, prefer_binary)


#: Why the last load of a source failed, by the same key: the material panel shows it without
#: loading anything while it draws.
_load_failures: dict[BTFFileKey, str] = {}


def load_cached(path: str, prefer_binary: bool = False) -> BTF:
    """The BTF at ``path`` (Blender's "//" relative paths allowed), loaded once per version.
    ``prefer_binary``: a BTFbase folder from its ``binary.btf`` alone (the material's Use
    binary.btf), not table by table from its text files."""
    key = file_key(path, prefer_binary)
    resolved = Path(key.path)
    if key not in _btf_cache:
        try:
            _btf_cache[key] = load_btf(resolved, prefer_binary=prefer_binary)
        except (BTFError, OSError, ValueError) as exc:
            _load_failures[key] = str(exc)
            raise
        _load_failures.pop(key, None)
    return _btf_cache[key]


def load_notes(path: str, prefer_binary: bool = False) -> list[str]:
    """What the last load of ``path`` warned about (a damaged text table read from
    ``binary.btf``, values it could not restore), when it is loaded; [] otherwise. Loads
    nothing: cheap enough for a panel's draw."""
    if not path:
        return []
    btf = _btf_cache.get(file_key(path, prefer_binary))
    return load_warnings(btf) if btf is not None else []


def known_problem(path: str) -> str:
    """Why ``path`` cannot render, as far as is known without loading it: no source, a path
    that does not exist, or the error of its last load at this version; '' otherwise. Cheap
    enough for a panel's draw (one stat)."""
    if not path:
        return "BTF enabled but no source set"
    key = file_key(path)
    if key.mtime < 0:
        return f"{key.path}: no such file or folder"
    return _load_failures.get(key, "")


class ExportedMaterial(NamedTuple):
    material: Material
    uv_map: str  # the UV map the material asks for; '' = the active render UV map


def export_material(material, messages: list[str]) -> ExportedMaterial:
    """``material``: a ``bpy.types.Material`` or None (an empty slot). A BTF that cannot be
    loaded gives a message and the analytic fallback, never an exception."""
    settings = getattr(material, "btf", None) if material is not None else None
    if settings is not None and settings.enabled:
        if not settings.source:
            messages.append(f"material {material.name!r}: BTF enabled but no source set")
        else:
            try:
                btf = load_cached(settings.source, settings.prefer_binary)
                # Damaged text tables taken from binary.btf: said on every render, not hidden.
                messages += [f"material {material.name!r}: {note}" for note in load_warnings(btf)]
                render = Material(
                    btf,
                    uv_scale=settings.uv_scale,
                    uv_rotation_rad=settings.uv_rotation,
                    exposure=settings.exposure,
                    name=material.name,
                    **placement(settings),
                )
                uv_map = BOX_MAPPED if settings.mapping == "BOX" else settings.uv_map
                return ExportedMaterial(render, uv_map)
            except (BTFError, OSError) as exc:
                messages.append(f"material {material.name!r}: {exc}")
    name = material.name if material is not None else DEFAULT_MATERIAL_NAME
    return ExportedMaterial(Material(analytic_btf(material, messages), name=name), "")


def placement(settings) -> dict:
    """The mapping fields of ``scene.Material`` from ``material.btf`` (blender/properties.py):
    a tile size of 0 means the one the BTF states."""
    size = tuple(float(x) for x in settings.tile_size_mm)
    return {
        "mapping": settings.mapping,
        "texel_filter": settings.texel_filter,
        "uv_offset": tuple(float(x) for x in settings.uv_offset),
        "real_world": bool(settings.use_real_world_size),
        "tile_size_mm": size if min(size) > 0.0 else None,
        "box_space": settings.box_space,
        "box_blend": float(settings.box_blend),
    }


@dataclass(frozen=True)
class SlotMaterial:
    """A material slot's render material: ``index`` into the scene's material list."""

    index: int
    uv_map: str
    name: str  # the Blender material's name; '' for an empty slot


@dataclass
class MaterialTable:
    """The scene's material list, built as slots are met: each Blender material is exported
    once, however many objects use it."""

    messages: list[str]
    materials: list[Material] = field(default_factory=list)
    _by_name: dict[str, SlotMaterial] = field(default_factory=dict)

    def slot(self, material) -> SlotMaterial:
        name = material.name if material is not None else ""
        if name not in self._by_name:
            exported = export_material(material, self.messages)
            self._by_name[name] = SlotMaterial(len(self.materials), exported.uv_map, name)
            self.materials.append(exported.material)
        return self._by_name[name]

"""The scene's light bake (``scene.btf_bake.path``, relative to the .blend like BTF sources; a
scene without one finds a bake at the default place beside the .blend, where the CLI's
``bake`` writes it) → the ``LightBake`` the drawer plays back (``Scene.light_bake``;
render/bake_playback.py says which meshes still match it). Read once per version of the file:
a viewport re-export after an edit costs a ``stat``, not a load. A missing or unreadable bake
is a message (the drawer then lights everything live), never an error that stops drawing.

The drawers' last word on it (``remember_status``) is kept per scene for the Light Bake panel:
the panel cannot afford to export and digest the scene on every redraw.
"""

from __future__ import annotations

from pathlib import Path

import bpy

from ...render.light_bake import LightBake, LightBakeError, default_path, load

#: Per absolute path: (its mtime and size when read, the bake). One bake per scene of a file,
#: so the dictionary is bounded by the scenes ever drawn in this session.
_loaded: dict[str, tuple[tuple[int, int], LightBake]] = {}
_status: dict[str, str] = {}


def scene_light_bake(scene, messages: list[str]) -> LightBake | None:
    """The bake ``scene`` points to, or None (no bake set; a missing or unreadable one, said
    in ``messages``)."""
    props = getattr(scene, "btf_bake", None)
    relative = props.path if props is not None else ""
    if not relative:  # a bake the command line wrote beside the file, if there is one
        beside = default_path(bpy.data.filepath, scene.name) if bpy.data.filepath else None
        if beside is None or not beside.is_file():
            return None
        relative = str(beside)
    path = Path(bpy.path.abspath(relative))
    try:
        stat = path.stat()
    except OSError:
        messages.append(
            f"Light bake {relative} is missing: objects are lit live; bake again (Render "
            "Properties › BTF › Light Bake for VR)"
        )
        return None
    key = (stat.st_mtime_ns, stat.st_size)
    cached = _loaded.get(str(path))
    if cached is not None and cached[0] == key:
        return cached[1]
    try:
        bake = load(path)
    except LightBakeError as exc:
        messages.append(f"{exc}; objects are lit live until then")
        return None
    _loaded[str(path)] = (key, bake)
    return bake


def remember_status(scene, drawer) -> None:
    """Keep the drawer's bake status line (render/bake_playback.py) for ``scene``'s panel."""
    status = getattr(drawer, "bake_status", None)
    name = getattr(scene, "original", scene).name
    if status is None:
        _status.pop(name, None)
    else:
        _status[name] = status.line()


def last_status(scene) -> str:
    """The last drawn status line of ``scene``'s bake ("" before a BTF view drew it)."""
    return _status.get(getattr(scene, "original", scene).name, "")

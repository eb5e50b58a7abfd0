"""A light bake as the drawer plays it back (gl/drawer.py, shaders/bake_lib.glsl): which of the
scene's meshes draw the baked light, which are stale and drawn with live light instead, and the
bake's tables in the textures the shader reads. bpy- and GL-free.

A mesh plays its bake back when the bake holds it (the same name, the same occurrence among
meshes of that name), baked it, and it is not stale (render/light_bake.py ``LightBake.stale``):
its own triangles, material, neighbours, the lights and the World are those the bake saw. Where
anything differs from the bake, the scene is analysed again (scene/bake_analysis.py, bounded
work: 16 ms on the demo) so that a mesh added or moved far away leaves the others' bakes be. Every
other mesh is drawn as before, with live (unshadowed) light, and the status says which and why,
for the panel, the VR HUD and the bridge's status.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.codecs.packed import TABLE_WIDTH, layout_stream
from ..scene.bake_analysis import bake_needs, neighbours_by_name
from ..scene.bake_points import pack_values
from ..scene.lights import pack_lights
from .light_bake import LightBake, mesh_digest, scene_digest

#: Names listed in a status line at most (the rest counted).
STATUS_NAMES = 4


@dataclass(frozen=True)
class BakeStatus:
    """``played``: meshes drawn with baked light; ``stale``: baked meshes drawn with live light
    because the scene changed since; ``missing``: meshes the bake never held that need one now
    (something was moved or added beside them); ``refused``: why nothing is played back
    (empty: no reason)."""

    played: tuple[str, ...] = ()
    stale: tuple[str, ...] = ()
    refused: str = ""
    missing: tuple[str, ...] = ()

    def line(self) -> str:
        """One line for the panel, the HUD and the bridge's status."""
        if self.refused:
            return f"Light bake not used: {self.refused}"
        parts = [f"baked light on {_names(self.played)}"] if self.played else []
        if self.stale:
            parts.append(f"stale, live light on {_names(self.stale)}: bake again")
        if self.missing:
            verb = "needs" if len(self.missing) == 1 else "need"
            parts.append(f"{_names(self.missing)} {verb} a bake now: bake again")
        return "Light bake: " + ("; ".join(parts) if parts else "nothing baked in this scene")


def _names(names: tuple[str, ...]) -> str:
    shown = ", ".join(names[:STATUS_NAMES])
    more = len(names) - STATUS_NAMES
    return f"{shown} and {more} more" if more > 0 else shown


@dataclass(frozen=True, eq=False)
class BakePlayback:
    """``status``: what the drawer says of the bake; ``first_triangle``: per scene mesh index
    that plays back, its first triangle in the bake (its triangle k is the bake's first + k).
    The textures' arrays are ``bake_textures``'s, the same for every drawer of one bake."""

    status: BakeStatus
    first_triangle: dict[int, int] = field(default_factory=dict)

    def bake_triangle(self, mesh_index: int) -> int:
        """The mesh's first bake triangle, −1 where it is drawn with live light."""
        return self.first_triangle.get(mesh_index, -1)


def bake_textures(bake: LightBake) -> tuple[np.ndarray, np.ndarray]:
    """The bake as shaders/bake_lib.glsl reads it: (rows, TABLE_WIDTH) float32 index stream
    ([V, where tri_points start, per triangle (cuts, first)…, tri_points…]) and (rows,
    TABLE_WIDTH, 4) float32 values, texel point·(V² + 1) + bin, then the point's light
    direction (scene/bake_points.py ``pack_values``)."""
    a = bake.arrays
    pairs = np.column_stack([a["tri_cuts"], a["tri_first"]]).ravel()
    head = [bake.view_bins, 2 + len(pairs)]
    index = layout_stream(np.concatenate([head, pairs, a["tri_points"]]).astype(np.float64))
    packed = pack_values(a["ratio"], a["light_dir"]).reshape(-1, 4)
    rows = max(1, -(-len(packed) // TABLE_WIDTH))
    values = np.zeros((rows * TABLE_WIDTH, 4), np.float32)
    values[: len(packed)] = packed
    return index, values.reshape(rows, TABLE_WIDTH, 4)


def texture_rows(bake: LightBake) -> int:
    """The taller of the two textures' heights (``bake_textures``) without building them."""
    a = bake.arrays
    index = 2 + 2 * len(a["tri_cuts"]) + len(a["tri_points"])
    values = a["ratio"].shape[0] * (a["ratio"].shape[1] + 1)
    return -(-max(index, values, 1) // TABLE_WIDTH)


class DigestCache:
    """Mesh and scene digests kept across drawers by the identity of what they digest, so a
    viewport edit hashes only what changed (a digest reads every triangle, and the World's
    every pixel: ~25 ms for a 2k map)."""

    def __init__(self, previous: DigestCache | None = None):
        self._meshes: dict[tuple, str] = {}
        self._old = previous._meshes if previous is not None else {}
        self._scene = previous._scene if previous is not None else None

    def mesh(self, scene, mesh, key: tuple, corners: np.ndarray) -> str:
        """``mesh_digest`` of ``mesh`` whose world-space ``corners`` are kept under ``key``
        (gl/drawer.py ``_mesh_key``: the same arrays at the same world matrix)."""
        material = scene.materials[mesh.material]
        block = material.block(mesh.material, mesh, scene.metres_per_unit)
        full = (key, block.tobytes(), id(material.btf), material.name)
        value = self._meshes.get(full) or self._old.get(full)
        if value is None:
            value = mesh_digest(scene, mesh, corners)
        self._meshes[full] = value
        return value

    def scene(self, scene) -> str:
        env = scene.environment
        key = (id(env), pack_lights(scene.lights).tobytes())
        if self._scene is None or self._scene[0] != key:
            self._scene = (key, env, scene_digest(scene))  # env kept: its id stays its own
        return self._scene[2]


def plan(
    bake: LightBake,
    scene,
    digests: list[str],
    triangles: list[int],
    current_scene_digest: str,
    max_rows: int,
) -> BakePlayback:
    """Which of ``scene``'s meshes play ``bake`` back. ``digests`` and ``triangles``: each
    mesh's ``mesh_digest`` and drawn triangle count (of its ``world_space_corners``), in order;
    ``max_rows``: the device's texture limit."""
    rows = texture_rows(bake)
    if rows > max_rows:
        return BakePlayback(
            BakeStatus(
                refused=f"its tables need textures {rows} rows tall, over this GPU's "
                f"{max_rows}: bake with a larger spacing or fewer view directions"
            )
        )
    by_name = {m.name: d for m, d in zip(scene.meshes, digests, strict=True)}
    recorded = {m.name: m.digest for m in bake.meshes}
    # the analysis only where something moved, was added or went: it says who is beside whom now
    needs = bake_needs(scene) if by_name != recorded else None
    neighbours = neighbours_by_name(needs) if needs is not None else None
    stale = set(bake.stale(by_name, current_scene_digest, neighbours=neighbours))
    missing = bake.missing([n.name for n in needs if n.anything]) if needs is not None else []
    first = bake.arrays["mesh_first_triangle"]
    records: dict[str, list[int]] = {}  # bake meshes by name, in order
    for index, record in enumerate(bake.meshes):
        records.setdefault(record.name, []).append(index)
    seen: dict[str, int] = {}
    played, stale_names, first_triangle = [], [], {}
    for i, (mesh, digest, count) in enumerate(zip(scene.meshes, digests, triangles, strict=True)):
        occurrence = seen.get(mesh.name, 0)
        seen[mesh.name] = occurrence + 1
        candidates = records.get(mesh.name, [])
        if occurrence >= len(candidates) or not bake.meshes[candidates[occurrence]].baked:
            continue  # never baked: live light is all it had
        b = candidates[occurrence]
        record = bake.meshes[b]
        baked = int(first[b + 1] - first[b]) if b + 1 < len(first) else -1
        if mesh.name in stale or record.digest != digest or baked != count:
            stale_names.append(mesh.name)
            continue
        first_triangle[i] = int(first[b])
        played.append(mesh.name)
    status = BakeStatus(tuple(played), tuple(stale_names), missing=tuple(missing))
    return BakePlayback(status, first_triangle)

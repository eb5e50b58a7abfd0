"""A light bake as data: what was baked (the bake points, the light per point and view bin),
with what knobs, for which objects and why, and what each object's bake depended on, so a later
look can tell which bakes a change has made stale. bpy- and device-free; written whole through
core/fileio.py (never half a file under the bake's name) as one ``.npz`` beside the .blend.

Staleness: each mesh's digest covers its world-space triangles and its material's identity
(codec, size, placement); the scene's covers Blender's lights and the World. A mesh "differs"
when its digest changed, when it is gone from the scene or when it was added to it. A baked
mesh M's bake is stale (``LightBake.stale``) when

- the lights or the World changed (every baked mesh), or
- M itself differs (moved, edited, re-materialed, gone), or
- a mesh that differs is among M's neighbours (the meshes that may shadow or reflect onto it,
  scene/bake_analysis.py): those it was baked beside (``MeshBake.neighbours``, the bake's own
  record) or, where the current scene's analysis is given (``neighbours``), those beside it
  now. The old ones catch a mesh moved away (its shadow must go), the new ones a mesh moved
  or added next to M.

Without the current analysis, where a mesh added to the scene stands is not known: it makes
every bake stale (conservative). Only the first ring of neighbours counts, as the analysis
itself reasons: light that reaches M after bounces off a neighbour N changes when a mesh
moves next to N but not next to M, and that change is not tracked (a user bakes again with
Re-bake Everything / ``--all``).

Staleness says whether a bake still holds, not whether it is still needed: a mesh baked
earlier that the current analysis would not bake (nothing beside it any more, and unchanged)
is not stale, its values can still be played back; a re-bake simply does not bake it again.
A mesh that needs a bake now and has none is ``LightBake.missing``.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import BTFError
from ..core.fileio import atomic_write
from ..scene.lights import pack_lights

#: The file format's version: a reader refuses another. 2: the meshes' triangle ranges
#: (``mesh_first_triangle``, what playback finds a mesh's bake by) and two-level mesh digests.
#: 3: an analytic material's values are its traced light over its unshadowed light (a ratio,
#: kernels/include/btf_bake.h ``bake_over_unshadowed``), no longer the light itself.
#: 4: per point its light's direction (``light_dir``), the one a measured material's response
#: is to (kernels/include/btf_bake.h ``bake_response``), no longer the normal.
FORMAT_VERSION = 4
SUFFIX = ".light_bake.npz"
#: The grid's arrays as they travel (scene/bake_points.py BakeGrid); footprints stay behind.
GRID_ARRAYS = (
    "positions",
    "normals",
    "tri_cuts",
    "tri_first",
    "tri_points",
    "point_mesh",
    "mesh_first_triangle",
)
#: The bake's own arrays: per point and view bin its light per unit response, per point the
#: direction of the light the response is to (scene/bake_points.py "Light direction").
VALUE_ARRAYS = ("ratio", "light_dir")


def default_path(blend_path: str | Path, scene_name: str) -> Path:
    """Beside the .blend: ``<file>.<scene>.light_bake.npz`` (one bake per scene of a file), where
    the operator and the CLI write a bake and where a scene without a bake path finds one."""
    blend = Path(blend_path)
    return blend.with_name(f"{blend.stem}.{scene_name}{SUFFIX}")


class LightBakeError(BTFError):
    """A bake file that cannot be read: damaged, foreign or of another version."""


@dataclass
class MeshBake:
    """One mesh's line of the bake report."""

    name: str
    digest: str
    baked: bool
    shadows: bool
    interreflection: bool
    reason: str
    neighbours: list[str] = field(default_factory=list)
    points: int = 0
    seconds: float = 0.0
    #: Its values were copied from the last bake, not traced: nothing its bake depends on
    #: changed since (the module's rule); ``seconds`` is then 0.
    kept: bool = False
    #: Why it was traced although a last bake was given (knobs that differ, what changed, not
    #: baked last time); empty when it was kept or there was no last bake to keep from.
    rebaked: str = ""

    def line(self) -> str:
        """The panel's one line for this mesh."""
        what = [
            e
            for e, on in (("shadows", self.shadows), ("interreflection", self.interreflection))
            if on
        ]
        if not self.baked:
            return f"{self.name}: not baked ({self.reason})"
        if self.kept:
            return (
                f"{self.name}: {' + '.join(what)} baked at {self.points} points "
                f"(kept: unchanged since the last bake; {self.reason})"
            )
        again = f"; re-baked: {self.rebaked}" if self.rebaked else ""
        return (
            f"{self.name}: {' + '.join(what)} baked at {self.points} points in "
            f"{self.seconds:.1f} s ({self.reason}){again}"
        )


@dataclass
class LightBake:
    """``arrays``: the grid's (GRID_ARRAYS), ``ratio`` (P, V², 3) float32 and ``light_dir``
    (P, 3) float32 unit vectors (VALUE_ARRAYS); ``knobs``: the bake's settings (spacing,
    view_bins, samples, bounces, footprint)."""

    arrays: dict[str, np.ndarray]
    knobs: dict
    meshes: list[MeshBake]
    scene_digest: str
    seconds: float = 0.0

    @property
    def view_bins(self) -> int:
        return int(self.knobs["view_bins"])

    def mesh_triangles(self, name: str) -> tuple[int, int] | None:
        """The bake's triangles [first, end) of the baked mesh ``name`` (its triangles in the
        order ``Mesh.world_space_corners`` gives them); None where it was not baked."""
        first = self.arrays["mesh_first_triangle"]
        for index, mesh in enumerate(self.meshes):
            if mesh.name == name and mesh.baked and index + 1 < len(first):
                return int(first[index]), int(first[index + 1])
        return None

    @property
    def nbytes(self) -> int:
        """What playback uploads: the per-triangle tables and the values."""
        return int(sum(a.nbytes for a in self.arrays.values()))

    def report(self) -> dict:
        return {
            "version": FORMAT_VERSION,
            "knobs": self.knobs,
            "seconds": round(self.seconds, 3),
            "bytes": self.nbytes,
            "meshes": [asdict(m) for m in self.meshes],
        }

    def stale(
        self,
        mesh_digests: dict[str, str],
        scene_digest: str,
        *,
        neighbours: dict[str, list[str]] | None = None,
    ) -> list[str]:
        """Names of the baked meshes whose bake no longer holds, in the bake's order (the
        module's rule). ``mesh_digests``: the current scene's, by name; ``neighbours``: per
        current mesh, the meshes beside it now (scene/bake_analysis.py
        ``current_neighbours``); None, or a mesh it has no entry for: any mesh added to the
        scene makes that bake stale."""
        return list(self.why_stale(mesh_digests, scene_digest, neighbours=neighbours))

    def why_stale(
        self,
        mesh_digests: dict[str, str],
        scene_digest: str,
        *,
        neighbours: dict[str, list[str]] | None = None,
    ) -> dict[str, str]:
        """``stale``'s names, each with why in a few words (for the report)."""
        baked = [m for m in self.meshes if m.baked]
        if scene_digest != self.scene_digest:
            return {m.name: "the lights or the World changed" for m in baked}
        differ = _differ({m.name: m.digest for m in self.meshes}, mesh_digests)
        added = [name for name, how in differ.items() if how == "added"]
        out = {}
        for mesh in baked:
            now = None if neighbours is None else neighbours.get(mesh.name)
            if why := _why_stale(mesh, differ, added, now):
                out[mesh.name] = why
        return out

    def missing(self, needed: Iterable[str]) -> list[str]:
        """Of ``needed`` (the meshes the current analysis would bake: ``BakeNeeds.anything``),
        those this bake has no values for, in the given order: "X needs a bake"."""
        baked = {m.name for m in self.meshes if m.baked}
        return [name for name in needed if name not in baked]

    def save(self, path: str | Path) -> Path:
        meta = json.dumps({**self.report(), "scene_digest": self.scene_digest})

        def write(f) -> None:
            np.savez(f, meta=np.frombuffer(meta.encode(), np.uint8), **self.arrays)

        return atomic_write(path, write)


#: How a neighbour differs → what the stale reason says of it.
_VERBS = {"changed": "beside it changed", "gone": "beside it is gone", "added": "added beside it"}


def _differ(old: dict[str, str], new: dict[str, str]) -> dict[str, str]:
    """The meshes whose digest is not the same in ``old`` and ``new`` (by name), each with how
    it differs: "changed", "gone" (only in ``old``) or "added" (only in ``new``)."""
    return {
        name: "added" if name not in old else "gone" if name not in new else "changed"
        for name in dict.fromkeys([*old, *new])
        if old.get(name) != new.get(name)
    }


def _why_stale(
    mesh: MeshBake, differ: dict[str, str], added: list[str], now: list[str] | None
) -> str:
    """Why the baked ``mesh`` is stale (the module's rule), "" where it is not; ``now``: its
    neighbours in the current analysis, None where not known."""
    if mesh.name in differ:
        return "it changed" if differ[mesh.name] == "changed" else "it is gone"
    if now is None and added:  # where the new ones stand is not known: any may matter
        return f"{_quoted(added)} added to the scene"
    near = [n for n in dict.fromkeys([*mesh.neighbours, *(now or ())]) if n in differ]
    return "; ".join(
        f"{_quoted(names)} {verb}"
        for how, verb in _VERBS.items()
        if (names := [n for n in near if differ[n] == how])
    )


def _quoted(names: list[str], most: int = 3) -> str:
    """Names for a one-line reason: the first ``most``, then how many more."""
    text = ", ".join(f"'{n}'" for n in names[:most])
    return text + (f" and {len(names) - most} more" if len(names) > most else "")


def load(path: str | Path) -> LightBake:
    """The bake at ``path``; LightBakeError saying what is wrong where it cannot be used."""
    try:
        with np.load(Path(path), allow_pickle=False) as data:
            meta = json.loads(bytes(data["meta"]).decode())
            version = meta.get("version")
            if version == FORMAT_VERSION:  # another version's arrays may differ
                arrays = {k: data[k] for k in (*GRID_ARRAYS, *VALUE_ARRAYS)}
        if version == FORMAT_VERSION:
            bins = int(meta["knobs"]["view_bins"]) ** 2
            meshes = [MeshBake(**m) for m in meta["meshes"]]
            bake = LightBake(arrays, meta["knobs"], meshes, meta["scene_digest"], meta["seconds"])
    # A damaged zip raises BadZipFile, EOFError or NotImplementedError (a flipped method
    # byte); foreign meta KeyError, TypeError or AttributeError: all mean "not ours, whole".
    except (
        OSError,
        ValueError,
        KeyError,
        TypeError,
        AttributeError,
        EOFError,
        NotImplementedError,
        zipfile.BadZipFile,
    ) as exc:
        raise LightBakeError(f"{path}: not a readable light bake ({exc}); bake again") from exc
    if version != FORMAT_VERSION:
        raise LightBakeError(
            f"{path}: light bake version {version}, this build reads {FORMAT_VERSION}; bake again"
        )
    ratio, light_dir, points = arrays["ratio"], arrays["light_dir"], len(arrays["positions"])
    if (
        ratio.shape != (points, bins, 3)
        or light_dir.shape != (points, 3)
        or not (np.all(np.isfinite(ratio)) and np.all(np.isfinite(light_dir)))
    ):
        raise LightBakeError(f"{path}: its values do not match its points; bake again")
    return bake


def mesh_digest(scene, mesh, corners: np.ndarray | None = None) -> str:
    """A mesh's digest: its world-space triangles (``corners``: its ``world_space_corners()``
    where the caller has them already) and its material's identity and placement on it."""
    if corners is None:
        corners = mesh.world_space_corners()
    material = scene.materials[mesh.material]
    block = material.block(mesh.material, mesh, scene.metres_per_unit)
    meta = material.btf.meta
    return digest(digest(corners), block, meta.codec, meta.width, meta.height, material.name)


def mesh_digests(scene) -> dict[str, str]:
    """Each mesh's ``mesh_digest`` by name."""
    return {mesh.name: mesh_digest(scene, mesh) for mesh in scene.meshes}


def scene_digest(scene) -> str:
    """The lights' and the World's digest: a change there makes every bake stale."""
    env = scene.environment
    return digest(pack_lights(scene.lights), env.radiance, env.rotation_z_rad)


def digest(*parts) -> str:
    """A short digest of arrays and plain values (JSON-able), in order."""
    h = hashlib.blake2b(digest_size=12)
    for part in parts:
        if isinstance(part, np.ndarray):
            h.update(np.ascontiguousarray(part).tobytes())
            h.update(str((part.dtype, part.shape)).encode())
        else:
            h.update(json.dumps(part, sort_keys=True, default=str).encode())
    return h.hexdigest()

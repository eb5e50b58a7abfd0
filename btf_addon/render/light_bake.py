"""A light bake as data: what was baked (the bake points, the light per point and view bin),
with what knobs, for which objects and why, and what each object's bake depended on, so a later
look can tell which bakes a change has made stale. bpy- and device-free; written whole through
core/fileio.py (never half a file under the bake's name) as one ``.npz`` beside the .blend.

Staleness: each mesh's digest covers its world-space triangles and its material's identity
(codec, size, placement); the scene's covers Blender's lights and the World. A mesh's bake is
stale when its own digest changed, when the digest of a mesh it was baked beside (shadow or
reflection: ``neighbours``) changed, when the lights or the World changed, or when a mesh was
added (it may stand in front of any of them).
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import BTFError
from ..core.fileio import atomic_write
from ..scene.lights import pack_lights

#: The file format's version: a reader refuses another. 2: the meshes' triangle ranges
#: (``mesh_first_triangle``, what playback finds a mesh's bake by) and two-level mesh digests.
FORMAT_VERSION = 2
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

    def line(self) -> str:
        """The panel's one line for this mesh."""
        what = [
            e
            for e, on in (("shadows", self.shadows), ("interreflection", self.interreflection))
            if on
        ]
        if not self.baked:
            return f"{self.name}: not baked ({self.reason})"
        return (
            f"{self.name}: {' + '.join(what)} baked at {self.points} points in "
            f"{self.seconds:.1f} s ({self.reason})"
        )


@dataclass
class LightBake:
    """``arrays``: the grid's (GRID_ARRAYS) and ``ratio`` (P, V², 3) float32; ``knobs``: the
    bake's settings (spacing, view_bins, samples, bounces, footprint)."""

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

    def stale(self, mesh_digests: dict[str, str], scene_digest: str) -> list[str]:
        """Names of the baked meshes whose bake no longer holds (the module's rule); a mesh
        gone from the scene is stale too, and a mesh added to it makes every bake stale (where
        it stands is not known here: it may shadow or reflect onto any of them)."""
        added = set(mesh_digests) - {m.name for m in self.meshes}
        if scene_digest != self.scene_digest or added:
            return [m.name for m in self.meshes if m.baked]
        changed = {m.name for m in self.meshes if mesh_digests.get(m.name) != m.digest}
        return [
            m.name
            for m in self.meshes
            if m.baked and (m.name in changed or changed & set(m.neighbours))
        ]

    def save(self, path: str | Path) -> Path:
        meta = json.dumps({**self.report(), "scene_digest": self.scene_digest})

        def write(f) -> None:
            np.savez(f, meta=np.frombuffer(meta.encode(), np.uint8), **self.arrays)

        return atomic_write(path, write)


def load(path: str | Path) -> LightBake:
    """The bake at ``path``; LightBakeError saying what is wrong where it cannot be used."""
    try:
        with np.load(Path(path), allow_pickle=False) as data:
            meta = json.loads(bytes(data["meta"]).decode())
            arrays = {k: data[k] for k in (*GRID_ARRAYS, "ratio")}
        version = meta.get("version")
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
    ratio = arrays["ratio"]
    if ratio.shape != (len(arrays["positions"]), bins, 3) or not np.all(np.isfinite(ratio)):
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

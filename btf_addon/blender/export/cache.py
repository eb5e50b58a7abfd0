"""What earlier exports produced, so that a viewport re-exports only what changed.

Keys and entries are frozen dataclasses rather than tuples: a key compares equal only to a key
of its own kind (never to a plain tuple that happens to hold the same items), and every field
is read by name.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from ...core.sampling.envmap import Environment
from ...scene.scene import Mesh


@dataclass(frozen=True)
class MeshKey:
    """One evaluated geometry. Geometry-nodes instances come as the generating object with other
    mesh data (all instances of one geometry share it): the data identifies the geometry, the
    object's name is what the depsgraph's updates (and so invalidation) speak of."""

    object_name: str
    data_name: str
    data_pointer: int

    @classmethod
    def of(cls, obj) -> MeshKey:
        """The key of an evaluated object (``depsgraph.object_instances[i].object``)."""
        name = obj.original.name if obj.original is not None else obj.name
        data = obj.data
        return cls(name, data.name if data else "", data.as_pointer() if data else 0)


@dataclass(frozen=True)
class CachedMesh:
    """An object's meshes in object space, one per material slot in use (``Mesh.material`` is
    the slot index), the names of the materials in its slots ("" for an empty slot: a
    material's UV map choice changes the exported UVs, so editing it invalidates the entry) and
    the messages the export gave."""

    meshes: tuple[Mesh, ...]
    material_names: tuple[str, ...]
    messages: tuple[str, ...]


@dataclass(frozen=True)
class CachedEnvironment:
    """The World's environment; ``world_name`` is "" when the scene has no World."""

    world_name: str
    environment: Environment
    messages: tuple[str, ...]


@dataclass
class ExportCache:
    """Meshes per ``MeshKey`` and the World's environment. World matrices and the material list
    are rebuilt on every export, which is cheap."""

    meshes: dict[MeshKey, CachedMesh] = field(default_factory=dict)
    environment: CachedEnvironment | None = None

    def invalidate(
        self, objects: Iterable[str] = (), materials: Iterable[str] = (), world: bool = False
    ) -> None:
        """Forget the meshes of these objects and of every object with one of these materials in
        a slot, and the environment if ``world``. (``changed_ids``' result unpacks into it.)"""
        objects, materials = set(objects), set(materials)
        for key, entry in list(self.meshes.items()):
            if key.object_name in objects or materials.intersection(entry.material_names):
                del self.meshes[key]
        if world:
            self.environment = None

    def keep_only(self, used: set[MeshKey]) -> None:
        """Drop entries the last export did not use (deleted objects, replaced evaluated data)."""
        for key in set(self.meshes) - used:
            del self.meshes[key]

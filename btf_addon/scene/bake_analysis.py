"""Which light effects a bake of each mesh must precompute, because the live drawer omits them.

The viewport drawer (gl/drawer.py) lights every surface with unshadowed lights and no bounced
light. A bake stores what it leaves out, per mesh; this module decides whether there is any:

- shadows: geometry can block light reaching a point only from the point's front side (light
  from behind is cut by n·l anyway), so only geometry in front of a face's plane matters:
  another mesh with a vertex there (a triangle reaches into a half-space only if one of its
  vertices does, so testing vertices is exact for each face's plane), or the mesh itself when
  it is not convex (analysis.py is_convex: no vertex in front of any face's plane).
- interreflection: a surface reflects from its front side (the side its normals point to; a
  BTF is measured over that hemisphere), so another mesh reflects onto this one only when each
  lies in front of some face of the other (they see each other); a non-convex mesh sees itself.

Conservative: "in front of the plane" is not "visible" (something may stand between, the part
in front may lie beside the face), so a bake may be asked for nothing, never skipped when
needed. Each pair first tests the other mesh's bounding box against every face (its support
n·c + |n|·h, exact for the box, so never misses), then the box's candidate faces against the
vertices, block by block as is_convex does, stopping at the first vertex in front. Work is
counted in face × vertex tests done, for the whole scene; once MAX_BAKE_WORK is spent, a pair
keeps the box's verdict (True: assumed to shadow and reflect) and the reason says so.

Blender lights (``scene.lights``) are ignored: a light occludes nothing and reflects nothing,
so whether geometry can shadow or reflect onto a mesh does not depend on them (a bake with no
lights still has the World's shadows).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .analysis import CONVEX_TOLERANCE, CONVEXITY_BLOCK, MAX_CONVEXITY_WORK, _convex
from .scene import Scene

#: How far (× the scene's size) a vertex must lie in front of a face's plane to count. Relative
#: to the scene, not to either mesh: float32 rounding of world positions grows with the largest
#: mesh, and a tolerance relative to a small one would fall below it, so two coplanar floor
#: tiles, or a decal lying on a large floor, would count that rounding as "in front".
BAKE_TOLERANCE = CONVEX_TOLERANCE
#: Face × vertex tests for the whole scene; pairs past it are assumed to shadow and reflect.
MAX_BAKE_WORK = 50_000_000
#: What one pair costs beyond its tests (Python and numpy call overhead, ~10 µs), in tests:
#: it bounds the time of scenes of many tiny meshes (a million pairs of cubes) as well.
PAIR_COST = 1024


@dataclass(frozen=True)
class BakeNeeds:
    mesh: int  # index in scene.meshes
    name: str  # mesh.name
    shadows: bool
    interreflection: bool
    reason: str  # one line for the bake report
    neighbours: tuple[str, ...] = ()  # names of the other meshes that shadow or reflect onto it

    @property
    def anything(self) -> bool:
        return self.shadows or self.interreflection


@dataclass
class _Part:
    """One mesh in the scene's unit frame (centred on the scene, ÷ its size): front-facing
    planes (4, F) as [n, −n·o] and unique vertices (V, 4) as [p, 1], float32 for the products."""

    planes: np.ndarray
    points: np.ndarray
    centre: np.ndarray  # of the vertices' box, float64
    half: np.ndarray


def _part(corners: np.ndarray, centre: np.ndarray, scale: float) -> _Part | None:
    p = corners[:, :3].astype(np.float64).reshape(-1, 3, 3)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(n, axis=1)
    keep = length > 1e-20  # is_convex's own test, so both count the same faces
    if not keep.any():
        return None
    n = n[keep] / length[keep, None]
    # The front is the side the drawer shades: the corner normals', should the winding disagree.
    shading = corners[:, 3:6].astype(np.float64).reshape(-1, 3, 3)[keep].sum(axis=1)
    n[np.einsum("ij,ij->i", n, shading) < 0] *= -1
    planes = np.concatenate(
        [n, -np.einsum("ij,ij->i", n, (p[keep, 0] - centre) / scale)[:, None]], 1
    )
    flat = np.ascontiguousarray(p.reshape(-1, 3))
    _, first = np.unique(flat.view(np.dtype((np.void, 24))), return_index=True)
    points = np.ones((len(first), 4))
    points[:, :3] = (flat[first] - centre) / scale
    low, high = points[:, :3].min(axis=0), points[:, :3].max(axis=0)
    return _Part(
        planes.T.astype(np.float32), points.astype(np.float32), (low + high) / 2, (high - low) / 2
    )


def _in_front(face: _Part, other: _Part, budget: list[int]) -> tuple[bool, bool]:
    """(some vertex of ``other`` lies in front of some face of ``face``, the check was skipped
    for want of budget — the first is then True). ``budget``: [tests left], spent here."""
    cost = PAIR_COST + face.planes.shape[1]
    if cost > budget[0]:
        return True, True
    budget[0] -= cost
    n, d = face.planes[:3].T.astype(np.float64), face.planes[3].astype(np.float64)
    reach = n @ other.centre + np.abs(n) @ other.half + d  # the box's furthest point in front
    candidates = np.flatnonzero(reach > BAKE_TOLERANCE)
    # Faces the box reaches furthest first, in blocks growing from ~64k tests to is_convex's
    # (which bounds the product's memory): a vertex in front is likeliest there, so the usual
    # "yes" (a mesh on the ground) ends in the first small block and spends little budget.
    candidates = candidates[np.argsort(-reach[candidates], kind="stable")]
    block, most = (max(1, size // len(other.points)) for size in (1 << 16, CONVEXITY_BLOCK))
    start = 0
    while start < len(candidates):
        planes = face.planes[:, candidates[start : start + block]]
        start, block = start + block, min(2 * block, most)
        cost = planes.shape[1] * len(other.points)
        if cost > budget[0]:
            return True, True
        budget[0] -= cost
        if (other.points @ planes).max() > BAKE_TOLERANCE:
            return True, False
    return False, False


def _names(indices, names, most: int = 3) -> str:
    """Names for a one-line reason: the first ``most``, then how many more."""
    text = ", ".join(f"'{names[k]}'" for k in indices[:most])
    return text + (f" and {len(indices) - most} more" if len(indices) > most else "")


def bake_needs(scene: Scene) -> list[BakeNeeds]:
    """One BakeNeeds per mesh of ``scene``, in ``scene.meshes`` order."""
    corners = [m.world_space_corners() for m in scene.meshes]
    names = [m.name or f"mesh {k}" for k, m in enumerate(scene.meshes)]
    everything = np.concatenate([c[:, :3] for c in corners] + [np.zeros((0, 3), np.float32)])
    low, high = (everything.min(0), everything.max(0)) if len(everything) else (np.zeros(3),) * 2
    centre = (low.astype(np.float64) + high) / 2
    scale = max(float((high - low).max()), 1e-12)
    parts = [_part(c, centre, scale) if len(c) else None for c in corners]
    live = [k for k, part in enumerate(parts) if part is not None]
    budget = [MAX_BAKE_WORK]
    front, skipped = {}, set()  # front[(i, j)]: some of j lies in front of a face of i
    for i in live:
        for j in live:
            if i != j:
                front[i, j], skip = _in_front(parts[i], parts[j], budget)
                if skip:
                    skipped.add((i, j))
    out = []
    for i, name in enumerate(names):
        part = parts[i]
        if part is None:
            why = "empty: no triangles" if len(corners[i]) == 0 else "no triangle with area"
            out.append(BakeNeeds(i, name, False, False, f"{why}: nothing to light"))
            continue
        occluders = [j for j in live if j != i and front[i, j]]
        reflectors = [j for j in occluders if front[j, i]]
        convex = _convex(corners[i])
        reasons = []
        if not convex:
            if part.planes.shape[1] * len(part.points) > MAX_CONVEXITY_WORK:
                reasons.append("too large to prove convex: assumed to fold onto itself")
            else:
                reasons.append("non-convex: folds shadow and reflect onto itself")
        guessed = [j for j in occluders if (i, j) in skipped or (j, i) in skipped]
        if shown := [j for j in reflectors if j not in guessed]:
            reasons.append(
                f"{_names(shown, names)} and it face each other: shadows and interreflection"
            )
        if shown := [j for j in occluders if j not in reflectors and j not in guessed]:
            reasons.append(f"{_names(shown, names)} in front of it, facing away: shadows only")
        if guessed:
            reasons.append(
                f"check with {_names(guessed, names)} skipped past MAX_BAKE_WORK "
                "tests: assumed to shadow and reflect"
            )
        if not reasons:
            alone = len(live) == 1
            reasons.append(
                "alone and convex: nothing can shadow it or reflect onto it"
                if alone
                else "convex, no other mesh in front of it: nothing to bake"
            )
        out.append(
            BakeNeeds(
                i,
                name,
                not convex or bool(occluders),
                not convex or bool(reflectors),
                "; ".join(reasons),
                tuple(names[j] for j in occluders),
            )
        )
    return out


def neighbours_by_name(needs: list[BakeNeeds]) -> dict[str, list[str]]:
    """Per mesh of an analysis (``bake_needs``' result), the meshes that may shadow or reflect
    onto it: what render/light_bake.py ``LightBake.stale`` takes as ``neighbours``."""
    return {need.name: list(need.neighbours) for need in needs}


def current_neighbours(scene: Scene) -> dict[str, list[str]]:
    """``neighbours_by_name`` of the scene analysed now (``bake_needs``: its cost, bounded by
    MAX_BAKE_WORK; a caller that needs the analysis too passes its result to
    ``neighbours_by_name`` instead of analysing twice)."""
    return neighbours_by_name(bake_needs(scene))

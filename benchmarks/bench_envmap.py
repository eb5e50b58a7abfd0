"""Environment lighting: distribution build time, light generation time and irradiance error vs
the number of virtual lights N, for every studiolight bundled with Blender.

Error: mean over 26 normals (cube faces, edges, corners) of |E_N − E_ref| / |E_ref| (summed over
RGB), E_ref by quadrature over every pixel. Baseline side by side: uniform sphere sampling with
the same N and the same Sobol points (what importance sampling buys).
"""

from __future__ import annotations

import itertools

import numpy as np
from common import table, timed
from helpers import studiolights_dir

from btf_addon.core.formats.imageio import read_exr
from btf_addon.core.sampling.envmap import Environment, VirtualLights
from btf_addon.core.sampling.sequences import sobol_2d

COUNTS = (1, 5, 25, 100, 200, 1000)


def normals() -> np.ndarray:
    n = np.array([v for v in itertools.product((-1, 0, 1), repeat=3) if any(v)], dtype=float)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def uniform_lights(env: Environment, n: int) -> VirtualLights:
    u = sobol_2d(n, seed=0)
    z = 1 - 2 * u[:, 0]
    r = np.sqrt(np.maximum(0, 1 - z * z))
    d = np.column_stack([r * np.cos(2 * np.pi * u[:, 1]), r * np.sin(2 * np.pi * u[:, 1]), z])
    return VirtualLights(d, env.lookup(d), np.full(n, 1 / (4 * np.pi)))


def rel_error(est, ref):
    return float(np.mean(np.abs(est - ref).sum(1) / ref.sum(1)))


def main() -> str:
    rows = []
    nrm = normals()
    for path in sorted(studiolights_dir().glob("*.exr")):
        image = read_exr(path)
        t_build, env = timed(Environment, image, repeat=3)
        ref = env.irradiance_reference(nrm, supersample=2)
        t_lights, _ = timed(env.virtual_lights, 256, repeat=3)
        errs = [rel_error(env.virtual_lights(n).irradiance(nrm), ref) for n in COUNTS]
        uni = [rel_error(uniform_lights(env, n).irradiance(nrm), ref) for n in COUNTS]
        rows.append(
            [path.stem, round(t_build * 1000, 1), round(t_lights * 1000, 2)]
            + [f"{e:.3f} ({u / max(e, 1e-12):.1f}×)" for e, u in zip(errs, uni, strict=True)]
        )
    return table(
        ["map", "build ms", "256 lights ms"] + [f"N={n} err (uniform ÷ ours)" for n in COUNTS], rows
    )


if __name__ == "__main__":
    print(main())

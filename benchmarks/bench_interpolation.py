"""What angular resolution costs: interpolation error of tabulated BTFs vs grid density.

For each analytic preset, tabulate on ring grids of decreasing spacing and compare with the exact
value at 20,000 random off-grid directions (θ ≤ 75°, where measured data exists). Columns: grid
size, table memory per texel, tabulation time, evaluation time for the 20,000 queries, and the
relative RMSE. The exact evaluation time is printed alongside as the baseline.
"""

from __future__ import annotations

import numpy as np
from common import table, timed

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.grid import UBO2003, uniform_ring_grid

N = 20_000


def directions(rng, n, theta_max=75.0):
    ct = rng.uniform(np.cos(np.radians(theta_max)), 1.0, n)
    st = np.sqrt(1 - ct * ct)
    ph = rng.uniform(0, 2 * np.pi, n)
    return np.column_stack([st * np.cos(ph), st * np.sin(ph), ct])


def main() -> str:
    rng = np.random.default_rng(5)
    uv, wi, wo = rng.random((N, 2)), directions(rng, N), directions(rng, N)
    presets = [
        ("lambertian 0.8", LambertianBTF(0.8)),
        ("ggx r=0.6", GGXBTF(0.8, 0.6)),
        ("ggx r=0.3", GGXBTF(0.8, 0.3)),
        ("woven 4×4 texels", woven(texels=4, fine_per_texel=8)),
    ]
    grids = [
        ("UBO 15°", UBO2003),
        ("rings 10°", uniform_ring_grid(10.0)),
        ("rings 5°", uniform_ring_grid(5.0)),
    ]
    rows = []
    for name, btf in presets:
        t_exact, exact = timed(btf.evaluate, uv, wi, wo)
        rows.append([name, "exact", "-", "-", "-", round(t_exact, 3), 0.0])
        for gname, grid in grids:
            if name.startswith("woven") and grid.size > 200:
                continue  # ray-cast tabulation at 647² directions takes minutes: not worth it here
            t_tab, dense = timed(tabulate, btf, grid, grid)
            t_eval, approx = timed(dense.evaluate, uv, wi, wo)
            err = np.sqrt(np.mean((approx - exact) ** 2)) / np.sqrt(np.mean(exact**2))
            kib = grid.size * grid.size * 3 * 4 / 1024
            rows.append(
                [
                    name,
                    gname,
                    grid.size,
                    round(kib, 1),
                    round(t_tab, 2),
                    round(t_eval, 3),
                    round(float(err), 4),
                ]
            )
    return table(
        [
            "preset",
            "grid",
            "directions",
            "KiB per texel (float32)",
            "tabulate s",
            f"eval s ({N:,} q)",
            "relative RMSE",
        ],
        rows,
    )


if __name__ == "__main__":
    print(main())

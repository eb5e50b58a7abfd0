"""numpy decode throughput on the shared BTFbase materials.

Baselines measured side by side in the same run: the independent scalar decoder of the tests
(plain Python per query) and a Lambertian evaluation of the same queries (the cost of the shared
input handling alone).
"""

from __future__ import annotations

import numpy as np
from common import SHARED_BTFBASE, table, timed

from btf_addon.core.analytic import LambertianBTF
from btf_addon.core.mlvq import MLVQBTF

N = 1_000_000
N_SCALAR = 2_000


def main() -> str:
    rng = np.random.default_rng(1)
    q = np.column_stack(
        [
            rng.random(N),
            rng.random(N),
            rng.random(N) * 90,
            rng.random(N) * 360,
            rng.random(N) * 90,
            rng.random(N) * 360,
        ]
    )
    rows = []
    for name in ("alu", "wallpaper"):
        path = SHARED_BTFBASE / name
        if not path.is_dir():
            print(f"skipping {name}: {path} not found")
            continue
        from scalar_mlvq import ScalarMLVQ

        load_s, btf = timed(MLVQBTF.from_directory, path)
        t_vec, _ = timed(btf.evaluate_angles, q, repeat=2)
        ref = ScalarMLVQ(path)
        t_scalar, _ = timed(lambda r=ref: [r.decode(*row) for row in q[:N_SCALAR]])
        t_lambert, _ = timed(LambertianBTF(0.5).evaluate_angles, q, repeat=2)
        rows.append(
            [
                name,
                f"{btf.meta.width}×{btf.meta.height}",
                round(load_s, 2),
                f"{N / t_vec:,.0f}",
                f"{N_SCALAR / t_scalar:,.0f}",
                round((N / t_vec) / (N_SCALAR / t_scalar), 1),
                round(t_vec / t_lambert, 1),
            ]
        )
    return table(
        [
            "material",
            "texels",
            "load s",
            "numpy queries/s",
            "scalar queries/s",
            "numpy ÷ scalar speed",
            "cost × Lambertian",
        ],
        rows,
    )


if __name__ == "__main__":
    print(main())

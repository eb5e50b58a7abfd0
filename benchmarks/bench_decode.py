"""Decode throughput on the shared BTFbase materials: numpy reference and OpenCL.

Baselines measured side by side in the same run: the independent scalar decoder of the tests
(plain Python per query), a Lambertian evaluation of the same queries (the cost of the shared
input handling alone), and the numpy decoder for the OpenCL ratio. OpenCL times include the
host-side sanitising and the transfers, with the program already built (cached).
"""

from __future__ import annotations

import numpy as np
from common import SHARED_BTFBASE, table, timed
from helpers import random_queries

from btf_addon.core.analytic import LambertianBTF
from btf_addon.core.mlvq import MLVQBTF

N = 1_000_000
N_SCALAR = 2_000


def main() -> str:
    rng = np.random.default_rng(1)
    q = random_queries(rng, N)
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
        cl_rate, cl_name = "-", "-"
        from btf_addon.cl.context import OpenCLUnavailableError, create_context
        from btf_addon.cl.evaluate import device_btf

        try:
            ctx = create_context()
        except OpenCLUnavailableError as exc:  # a kernel that fails to compile is not skipped
            print(f"OpenCL skipped: {exc}")
        else:
            on_device = device_btf(btf, ctx)
            t_cl, _ = timed(on_device.evaluate_angles, q, repeat=2)
            cl_rate, cl_name = round(t_vec / t_cl, 2), ctx.device_name
        rows.append(
            [
                name,
                f"{btf.meta.width}×{btf.meta.height}",
                round(load_s, 2),
                f"{N / t_vec:,.0f}",
                f"{N_SCALAR / t_scalar:,.0f}",
                round((N / t_vec) / (N_SCALAR / t_scalar), 1),
                round(t_vec / t_lambert, 1),
                cl_rate,
                cl_name,
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
            "OpenCL ÷ numpy speed",
            "OpenCL device",
        ],
        rows,
    )


if __name__ == "__main__":
    print(main())

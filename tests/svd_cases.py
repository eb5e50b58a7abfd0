"""Small svd-codec BTFs shared by the OpenCL and GLSL parity tests."""

from __future__ import annotations

import dataclasses

import numpy as np

from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.codecs.svd import SVDBTF
from btf_addon.core.codecs.svd_build import factorise
from btf_addon.core.grid import uniform_ring_grid


def svd_cases() -> dict[str, SVDBTF]:
    """YUV at mixed ranks (the UBO2014 default), and the log-RGB model (exp on every channel)
    with the cosine not in the data, on a small woven material: 4×4 texels, 35 × 80 pairs."""
    src = tabulate(
        woven(texels=4, fine_per_texel=4), uniform_ring_grid(20.0), uniform_ring_grid(15.0)
    )
    yuv, _ = factorise(src.data * np.pi, src.view_grid, src.light_grid, ranks=(6, 3, 3))
    logs, _ = factorise(
        np.log(src.data * np.pi + 1e-5),
        src.view_grid,
        src.light_grid,
        ranks=(4, 4, 4),
        colour_model=0,
    )
    log_p = dataclasses.replace(logs.p, colour_model=12, cosine_in_data=False)
    return {
        "yuv": yuv,
        "log-rgb": SVDBTF(log_p, logs.u, logs.sv),
        "rotated-rings": SVDBTF(rotated_rings(yuv.p), yuv.u, yuv.sv),
    }


def rotated_rings(p):
    """The same factors on rings whose azimuths are rotated per ring and (for the views)
    unevenly spaced: what a file sampled otherwise than k·360°/n brings."""
    view_phi, light_phi = [], []
    for grid, out, uneven in ((p.view_grid, view_phi, True), (p.light_grid, light_phi, False)):
        for r, n in enumerate(grid.counts):
            k = np.arange(n) * 360.0 / n
            if uneven and n > 2:
                k = k + np.where(np.arange(n) % 2, 0.3 * 360.0 / n, 0.0)
            out.extend(((k + 5.0 * r) % 360.0 if n > 1 else k).tolist())
    sort = []
    for grid, phis in ((p.view_grid, view_phi), (p.light_grid, light_phi)):
        start, ordered = 0, []
        for n in grid.counts:
            ordered.extend(sorted(phis[start : start + n]))
            start += n
        sort.append(tuple(ordered))
    return dataclasses.replace(p, view_phi=sort[0], light_phi=sort[1])

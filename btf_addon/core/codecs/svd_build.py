"""Building svd BTFs (core/codecs/svd.py): the truncated per-channel SVD of measured values, and the
box-filtered reduced-resolution copy the GPU fallback (core/codecs/gpu_fit.py) draws."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import UnsupportedBTFError
from ..grid import UBO2003, RingGrid
from ..model import box_reduce
from .svd import _YUV_TO_RGB, SVDBTF, SVDParams

_RGB_TO_YUV = np.linalg.inv(_YUV_TO_RGB)


def factorise(
    data: np.ndarray,
    view_grid: RingGrid = UBO2003,
    light_grid: RingGrid = UBO2003,
    ranks: tuple[int, int, int] = (8, 8, 8),
    colour_model: int = 1,
    name: str = "svd",
    cosine_in_data: bool = True,
) -> tuple[SVDBTF, np.ndarray]:
    """Truncated per-channel SVD of measured values → (SVDBTF, relative truncation error per
    channel (3,): ‖dropped singular values‖ / ‖all‖, the Frobenius error of the rank-K fit).

    data: (n_views, n_lights, height, width, 3) RGB as reflectance factors (rgb_scale 1:
    value = data/π). colour_model: 0 (RGB) or 1 (YUV)."""
    data = np.asarray(data, dtype=np.float64)
    nv, nl, h, w, _ = data.shape
    if colour_model == 0:
        channels = data
    elif colour_model == 1:
        channels = data @ _RGB_TO_YUV.T
    else:
        raise UnsupportedBTFError("factorise writes the RGB (0) or YUV (1) colour models only")
    u, sv, errors = [], [], np.zeros(3)
    for c in range(3):
        m = channels[..., c].reshape(nv * nl, h * w)
        uu, s, vt = np.linalg.svd(m, full_matrices=False)
        k = max(1, min(ranks[c], len(s)))
        u.append(uu[:, :k])
        sv.append((s[:k, None] * vt[:k]).T)
        total = float(np.sqrt(np.sum(s**2)))
        errors[c] = float(np.sqrt(np.sum(s[k:] ** 2))) / total if total > 0 else 0.0
    params = SVDParams(
        name=name,
        width=w,
        height=h,
        view_grid=view_grid,
        light_grid=light_grid,
        colour_model=colour_model,
        pca_matrix=tuple(np.eye(3).ravel()),
        colour_mean=(0.0, 0.0, 0.0),
        rgb_scale=(1.0, 1.0, 1.0),
        cosine_in_data=cosine_in_data,
    )
    return SVDBTF(params, u, sv), errors


def reduce_resolution(btf: SVDBTF, factor: int) -> SVDBTF:
    """Texels averaged over factor × factor blocks (SV rows are linear in the value, so this is
    the box-filtered BTF for the linear colour models): the GPU fallback when a BTF is too large.
    Sizes not divisible by ``factor`` drop their last partial block."""
    p = btf.p
    sv = [box_reduce(a.reshape(p.height, p.width, -1), factor, p.name) for a in btf.sv]
    h, w = sv[0].shape[:2]
    sv = [a.reshape(h * w, -1) for a in sv]
    return SVDBTF(replace(p, width=w, height=h, name=f"{p.name} (1/{factor})"), btf.u, sv)

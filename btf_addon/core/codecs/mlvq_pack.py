"""The MLVQ codec's GPU tables (the packed layout of packed.py), read by ``mlvq_decode`` in
kernels/include/btf_packed.h and shaders/btf_mlvq_lib.glsl; the codec's registration with its
device id and this pack function. The decoder itself is mlvq.py (numpy, the reference)."""

from __future__ import annotations

import numpy as np

from ..errors import UnsupportedBTFError
from .mlvq import FLOAT_TABLES, INT_TABLES, MLVQBTF
from .packed import MAX_EXACT_INT, TableWriter, register_codec


def pack_mlvq(btf: MLVQBTF, out: TableWriter) -> None:
    """The 13 tables as they are (header slots by table name), then the decode's interleaved
    copies (``fast_tables``)."""
    p, t = btf.p, btf.t
    height, width = t["pdf6_slices"].shape
    out.set(
        n_beta=p.n_beta,
        n_alpha=p.n_alpha,
        n_theta=p.n_theta,
        n_phi=p.n_phi,
        width=width,
        height=height,
        rows_offset=p.rows_offset,
        cols_offset=p.cols_offset,
        hdr=int(p.hdr),
        cos_beta=int(p.use_cos_beta),
    )
    out.set(**{name: out.int_table(t[name]) for name in INT_TABLES})
    out.set(**{"f_" + name: out.float_table(t[name]) for name in FLOAT_TABLES})
    out.set(f_beta=out.float_table(p.beta_angles_deg()), hdr_value=p.hdr_value)
    fast_tables(t, out)


def fast_tables(t: dict[str, np.ndarray], out: TableWriter) -> None:
    """The MLVQ tables again, interleaved in the order the device decode reads them, so each
    step of its chain of dependent reads is one read of one cache line instead of two or three
    (docs/accuracy.md "BTFbase decoding"). Exact copies: every value is the original float32,
    every index an integer below 2^24 (exact as float32, which ``finish`` checks).

    f_mlvq6: per texel (pdf6 scale, pdf6 slot) — float2; f_mlvq4: per (slot, φ)
    (pdf4 scale, pdf3 row) — float2; f_mlvq3: per (row, θ) (pdf3 scale, luminance function,
    colour function, 0) — float4; f_mlvq2: per (luminance function, α) (pdf2 scale, pdf1
    curve) — float2; f_mlvq_ab: per (colour slice, β node) its (Cb, Cr) — float2, so the two
    nodes of a β interval are one 4-float read (index_ab and ab_colors resolved)."""
    f32 = np.float32

    def pairs(*columns: np.ndarray) -> np.ndarray:
        return np.stack([np.asarray(c).ravel().astype(f32) for c in columns], axis=-1)

    for name in ("pdf2_indices", "pdf3_slices", "pdf4_slices", "pdf6_slices", "pdf2_slices"):
        if t[name].size and int(t[name].max()) >= MAX_EXACT_INT:
            raise UnsupportedBTFError(f"MLVQ table {name} holds an index of 2^24 or more")
    idx2 = t["pdf3_slices"].ravel()
    fns = t["pdf2_indices"][idx2]
    f3 = pairs(t["pdf3_scale"], fns[:, 0], fns[:, 1], np.zeros(len(idx2)))
    out.align_floats(4)  # f_mlvq43 rows 16-byte aligned
    # f_mlvq43: per (pdf6 slot, φ, θ) the pdf4 → pdf3 chain resolved, (s4·s3, luminance fn,
    # colour fn, 0) — float4; θ and θ+1 are one 8-float read. The product is rounded once
    # from float64 (the reference multiplies the two float32 scales in float64).
    rows4 = t["pdf4_slices"].ravel()
    s43 = t["pdf4_scale"].ravel()[:, None].astype(np.float64) * t["pdf3_scale"][rows4]
    fns43 = t["pdf2_indices"][t["pdf3_slices"][rows4]]  # (slots·φ, θ, 2)
    f43 = pairs(s43, fns43[..., 0], fns43[..., 1], np.zeros(s43.size))
    out.set(f_mlvq43=out.float_table(f43))
    out.align_floats(4)  # f_mlvq3 rows 16-byte aligned
    out.set(
        f_mlvq3=out.float_table(f3),
        f_mlvq6=out.float_table(pairs(t["pdf6_scale"], t["pdf6_slices"])),
        f_mlvq4=out.float_table(pairs(t["pdf4_scale"], t["pdf4_slices"])),
        f_mlvq2=out.float_table(pairs(t["pdf2_scale"], t["pdf2_slices"])),
        f_mlvq_ab=out.float_table(t["ab_colors"][t["index_ab"]].astype(f32)),
    )


register_codec("mlvq", MLVQBTF, 1, pack_mlvq)

"""The MLVQ encoder's nearest-codeword step on an OpenCL device (kernels/encoder_assign.cl).

``OpenCLAssign(ctx)`` is a drop-in for ``core.encoders.kmeans.nearest`` (the encoder's
injectable ``assign``): the same scores (``score_weights``), the same tie rule (lowest index),
the scale recomputed in float64 on the host (``best_scales``). Only the argmax over codewords
runs on the device; float32 sums in another order than numpy's BLAS can swap near ties.

``opencl_assign_or_none()`` is what the CLI and the Blender operator pass: the device step on a
GPU, None (numpy) otherwise: on a CPU OpenCL driver (PoCL) numpy's BLAS product is faster,
measured in benchmarks/bench_compress.py.
"""

from __future__ import annotations

import numpy as np

from ..core.encoders.kmeans import best_scales, score_weights
from .context import CLContext, OpenCLUnavailableError, create_context
from .programs import build_program

#: Work-group size (rows sharing one staged codeword tile) and rows per launch (bounds the
#: transposed copy of x: 65 536 × 2541 float32 = 666 MB at level 3, so fewer rows there).
GROUP = 64
LAUNCH_ELEMENTS = 1 << 25


class OpenCLAssign:
    """``assign(x (N, D), centres (K, D), scale_free) -> (labels (N,) int64, scales (N,)
    float64)`` on one OpenCL device."""

    def __init__(self, cl_context: CLContext):
        import pyopencl as cl

        self._cl = cl
        self.ctx = cl_context
        program = build_program(cl_context.context, cl_context.device, "encoder_assign.cl", {})
        self.kernel = cl.Kernel(program, "assign_nearest")

    @property
    def device_name(self) -> str:
        return self.ctx.device_name

    def __call__(
        self, x: np.ndarray, centres: np.ndarray, scale_free: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        cl = self._cl
        n, d = len(x), int(np.shape(centres)[1])
        c = np.ascontiguousarray(centres, dtype=np.float32)
        w, bias, cc = score_weights(c, scale_free)
        labels = np.zeros(n, dtype=np.int64)
        scales = np.ones(n, dtype=np.float64)
        if n == 0 or len(c) == 0:
            return labels, scales
        mf = cl.mem_flags
        w_buf = cl.Buffer(self.ctx.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=w)
        b_buf = cl.Buffer(self.ctx.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=bias)
        rows = max(GROUP, LAUNCH_ELEMENTS // max(1, d) // GROUP * GROUP)
        for start in range(0, n, rows):
            xs = np.asarray(x[start : start + rows], dtype=np.float32)
            m = len(xs)
            xt = np.ascontiguousarray(xs.T)  # (d, m): neighbouring work-items, neighbouring reads
            x_buf = cl.Buffer(self.ctx.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=xt)
            out = np.empty(m, dtype=np.int32)
            out_buf = cl.Buffer(self.ctx.context, mf.WRITE_ONLY, out.nbytes)
            size = -(-m // GROUP) * GROUP
            self.kernel(
                self.ctx.queue,
                (size,),
                (GROUP,),
                x_buf,
                w_buf,
                b_buf,
                np.int32(m),
                np.int32(len(c)),
                np.int32(d),
                np.int32(1 if scale_free else 0),
                out_buf,
            )
            cl.enqueue_copy(self.ctx.queue, out, out_buf)
            best = out.astype(np.int64)
            labels[start : start + m] = best
            if scale_free:
                scales[start : start + m] = best_scales(xs, c, cc, best)
        return labels, scales


def opencl_assign_or_none(device_index: int | None = None) -> OpenCLAssign | None:
    """The device assign step when the chosen OpenCL device (default: the best) is a GPU;
    None (the encoder then uses numpy) without OpenCL or on a CPU driver, where numpy's BLAS
    is the faster of the two."""
    try:
        ctx = create_context(device_index)
    except OpenCLUnavailableError:
        return None
    import pyopencl as cl

    if not ctx.device.type & cl.device_type.GPU:
        return None
    return OpenCLAssign(ctx)

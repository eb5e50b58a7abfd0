"""BTF evaluation on an OpenCL device (kernels/btf_eval.cl), with the numpy codecs as reference.

``device_btf(btf, cl_context)`` wraps a core BTF in the one delegating wrapper
(core/model.py ``DelegatingBTF``): the base class still sanitises and chunks the queries on the
host (NaN/Inf, below-horizon and zero-length rows never reach the device); ``KernelEvaluator``
evaluates the valid rows from the packed table layout that the GLSL back end uses too
(btf_addon/core/packed.py).
"""

from __future__ import annotations

import numpy as np

from ..core.model import BTF, DelegatingBTF, Queries
from ..core.packed import pack
from .context import CLContext
from .programs import build_program


class KernelEvaluator:
    """Valid queries → (M, 3) float64 values by ``eval_btf`` on one device; the BTF's packed
    tables stay on the device between calls."""

    def __init__(self, btf: BTF, cl_context: CLContext):
        import pyopencl as cl

        packed = pack(btf)  # raises UnsupportedBTFError for procedural codecs
        self.ctx = cl_context
        self._cl = cl
        self.program = build_program(cl_context.context, cl_context.device, "btf_eval.cl", {})
        self.kernel = cl.Kernel(self.program, "eval_btf")  # retrieved once, reused per chunk
        self._ints = self._buffer(packed.ints.ravel())
        self._floats = self._buffer(packed.floats.ravel())

    def _buffer(self, array: np.ndarray):
        mf = self._cl.mem_flags
        return self._cl.Buffer(
            self.ctx.context,
            mf.READ_ONLY | mf.COPY_HOST_PTR,
            hostbuf=np.ascontiguousarray(array, dtype=np.float32),
        )

    def __call__(self, q: Queries) -> np.ndarray:
        cl = self._cl
        n = len(q.uv)
        out = np.empty((n, 3), dtype=np.float32)
        if n == 0:
            return out.astype(np.float64)
        rows = np.column_stack([q.uv, q.theta_i, q.phi_i, q.theta_v, q.phi_v])
        dirs = np.stack([q.wi, q.wo], axis=1).reshape(-1, 3)
        out_buf = cl.Buffer(self.ctx.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
        self.kernel(
            self.ctx.queue,
            (n,),
            None,
            self._buffer(rows),
            self._buffer(dirs),
            np.int32(n),
            self._ints,
            self._floats,
            out_buf,
        )
        cl.enqueue_copy(self.ctx.queue, out, out_buf)
        return out.astype(np.float64)


def device_btf(btf: BTF, cl_context: CLContext) -> DelegatingBTF:
    """``btf`` evaluated on the context's device (same ``meta``, ``tables()``, ``params()``)."""
    return DelegatingBTF(btf, KernelEvaluator(btf, cl_context))

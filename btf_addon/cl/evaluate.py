"""BTF evaluation on an OpenCL device (kernels/btf_eval.cl), with the numpy codecs as reference.

``device_btf(btf, cl_context)`` wraps a core BTF in the one delegating wrapper
(core/model.py ``DelegatingBTF``): the base class still sanitises and chunks the queries on the
host (NaN/Inf, below-horizon and zero-length rows never reach the device); ``KernelEvaluator``
evaluates the valid rows from the packed table layout that the GLSL back end uses too
(btf_addon/core/codecs/packed.py). MLVQ and dense materials go through ``eval_mlvq`` and
``eval_dense``, which on a CPU device decode a batch of queries per work-item, issuing the
batch's reads of each step before using any, so that their cache misses overlap
(docs/accuracy.md "BTFbase decoding").
"""

from __future__ import annotations

import numpy as np

from ..core.codecs.packed import pack
from ..core.model import BTF, DelegatingBTF, Queries, innermost
from .context import CLContext
from .programs import build_program


class KernelEvaluator:
    """Valid queries → (M, 3) float32 values (what the device computes; the base class
    clamps them into its float32 output) by ``batched_launch``'s kernel on one device; the
    BTF's packed tables stay on the device between calls."""

    def __init__(self, btf: BTF, cl_context: CLContext):
        import pyopencl as cl

        packed = pack(btf)  # raises UnsupportedBTFError for procedural codecs
        self.ctx = cl_context
        self._cl = cl
        name, self.batch, self.local_size = batched_launch(btf, cl_context.device)
        defines = {BATCH_DEFINES[name]: self.batch} if self.batch else {}
        self.program = build_program(cl_context.context, cl_context.device, "btf_eval.cl", defines)
        self.kernel = cl.Kernel(self.program, name)  # retrieved once, reused per chunk
        self._ints = self._buffer(packed.ints.ravel())
        self._floats = self._buffer(packed.floats.ravel())

    def _buffer(self, array: np.ndarray):
        mf = self._cl.mem_flags
        return self._cl.Buffer(
            self.ctx.context,
            mf.READ_ONLY | mf.COPY_HOST_PTR,
            hostbuf=np.ascontiguousarray(array, dtype=np.float32),
        )

    def launch_size(self, n: int) -> tuple[tuple[int], tuple[int] | None]:
        """(global size, local size) for n queries."""
        items = -(-n // self.batch) if self.batch else n
        if self.local_size is None:
            return (items,), None
        return (-(-items // self.local_size) * self.local_size,), (self.local_size,)

    def __call__(self, q: Queries) -> np.ndarray:
        cl = self._cl
        n = len(q.uv)
        out = np.empty((n, 3), dtype=np.float32)
        if n == 0:
            return out
        # written straight into the float32 layouts the kernel reads (no float64 copies)
        rows = np.empty((n, 6), dtype=np.float32)
        rows[:, :2], rows[:, 2], rows[:, 3] = q.uv, q.theta_i, q.phi_i
        rows[:, 4], rows[:, 5] = q.theta_v, q.phi_v
        dirs = np.empty((n, 2, 3), dtype=np.float32)
        dirs[:, 0], dirs[:, 1] = q.wi, q.wo
        out_buf = cl.Buffer(self.ctx.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
        self.kernel(
            self.ctx.queue,
            *self.launch_size(n),
            self._buffer(rows),
            self._buffer(dirs),
            np.int32(n),
            self._ints,
            self._floats,
            out_buf,
        )
        cl.enqueue_copy(self.ctx.queue, out, out_buf)
        return out


def batched_launch(btf: BTF, device) -> tuple[str, int, int | None]:
    """(kernel, queries per work-item, work-group size) for this material on this device: the
    batched decode of its codec (``eval_mlvq``, ``eval_dense``), or ``eval_btf`` with (0,
    None) for the others. A CPU decodes BATCH_CPU queries per work-item in groups of 16, so the
    cache misses of a batch overlap: PoCL keeps a group's private batches on one thread's
    stack, and its own choice of a large group overflowed it at 8 queries per work-item. A GPU
    hides the misses with its many work-items instead: one query each, its own group size."""
    import pyopencl as cl

    btf = innermost(btf)
    name = {"mlvq": "eval_mlvq", "dense": "eval_dense"}.get(btf.meta.codec)
    if name is None:
        return "eval_btf", 0, None
    if device.type & cl.device_type.CPU:
        return name, BATCH_CPU, 16
    return name, 1, None


#: Queries per work-item of the batched decodes on a CPU: 8 was the best of 1, 2, 4, 8, 16 in
#: the A/B runs of docs/accuracy-history.md (wallpaper random: 2× one query per work-item).
BATCH_CPU = 8
#: The define that sets each batched kernel's batch (kernels/btf_eval.cl).
BATCH_DEFINES = {"eval_mlvq": "MLVQ_BATCH", "eval_dense": "DENSE_BATCH"}


def device_btf(btf: BTF, cl_context: CLContext) -> DelegatingBTF:
    """``btf`` evaluated on the context's device (same ``meta``, ``tables()``, ``params()``)."""
    return DelegatingBTF(btf, KernelEvaluator(btf, cl_context))

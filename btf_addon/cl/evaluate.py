"""BTF evaluation on an OpenCL device (kernels/btf_eval.cl), with the numpy codecs as reference.

``DeviceBTF`` wraps a core BTF: the base class still sanitises and chunks the queries on the host
(NaN/Inf, below-horizon and zero-length rows never reach the device), and only valid rows are
evaluated by the kernel of the wrapped codec.
"""

from __future__ import annotations

import numpy as np

from ..core.analytic import GGXBTF, LambertianBTF
from ..core.errors import UnsupportedBTFError
from ..core.mlvq import MLVQBTF
from ..core.model import BTF, Queries
from .context import CLContext
from .programs import build_program

SUPPORTED = (MLVQBTF, LambertianBTF, GGXBTF)


class DeviceBTF(BTF):
    def __init__(self, btf: BTF, cl_context: CLContext):
        if not isinstance(btf, SUPPORTED):
            raise UnsupportedBTFError(
                f"the OpenCL back end does not evaluate {btf.meta.codec!r} BTFs yet; "
                "tabulate procedural presets first or use --backend numpy"
            )
        import pyopencl as cl

        self.btf = btf
        self.meta = btf.meta
        self.ctx = cl_context
        self._cl = cl
        defines = {}
        if isinstance(btf, MLVQBTF):
            defines = {"MLVQ_HDR": int(btf.p.hdr), "MLVQ_COS_BETA": int(btf.p.use_cos_beta)}
        program = build_program(cl_context.context, cl_context.device, "btf_eval.cl", defines)
        name = {MLVQBTF: "eval_mlvq", LambertianBTF: "eval_lambertian", GGXBTF: "eval_ggx"}
        self.kernel = cl.Kernel(program, name[type(btf)])  # retrieved once, reused per chunk
        self._tables = self._upload_tables() if isinstance(btf, MLVQBTF) else None

    def _buffer(self, array: np.ndarray):
        mf = self._cl.mem_flags
        return self._cl.Buffer(
            self.ctx.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(array)
        )

    def _upload_tables(self):
        t = self.btf.t
        order = [
            ("pdf1", np.float32),
            ("ab_colors", np.float32),
            ("index_ab", np.int32),
            ("pdf2_colours", np.int32),
            ("pdf2_slices", np.int32),
            ("pdf2_scale", np.float32),
            ("pdf2_indices", np.int32),
            ("pdf3_slices", np.int32),
            ("pdf3_scale", np.float32),
            ("pdf4_slices", np.int32),
            ("pdf4_scale", np.float32),
            ("pdf6_slices", np.int32),
            ("pdf6_scale", np.float32),
        ]
        buffers = [self._buffer(t[name].astype(dtype)) for name, dtype in order]
        buffers.append(self._buffer(self.btf.p.beta_angles_deg().astype(np.float32)))
        return buffers

    def _evaluate_valid(self, q: Queries) -> np.ndarray:
        cl = self._cl
        n = len(q.uv)
        out = np.empty((n, 3), dtype=np.float32)
        if n == 0:
            return out
        out_buf = cl.Buffer(self.ctx.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
        btf = self.btf
        if isinstance(btf, MLVQBTF):
            rows = np.column_stack([q.uv, q.theta_i, q.phi_i, q.theta_v, q.phi_v]).astype(
                np.float32
            )
            p = btf.p
            height, width = btf.t["pdf6_slices"].shape
            self.kernel(
                self.ctx.queue,
                (n,),
                None,
                self._buffer(rows),
                np.int32(n),
                np.float32(btf.meta.value_scale),
                out_buf,
                *self._tables,
                np.array([p.n_beta, p.n_alpha, p.n_theta, p.n_phi], dtype=np.int32),
                np.array([width, height, p.rows_offset, p.cols_offset], dtype=np.int32),
                np.float32(p.hdr_value),
            )
        elif isinstance(btf, LambertianBTF):
            albedo = np.array([*btf.albedo, 0.0], dtype=np.float32)  # float3 is 4 floats
            self.kernel(
                self.ctx.queue,
                (n,),
                None,
                self._buffer(q.wi.astype(np.float32)),
                np.int32(n),
                albedo,
                out_buf,
            )
        else:
            albedo = np.array([*btf.albedo, 0.0], dtype=np.float32)
            self.kernel(
                self.ctx.queue,
                (n,),
                None,
                self._buffer(q.wi.astype(np.float32)),
                self._buffer(q.wo.astype(np.float32)),
                np.int32(n),
                albedo,
                np.float32(btf.alpha2),
                out_buf,
            )
        cl.enqueue_copy(self.ctx.queue, out, out_buf)
        return out.astype(np.float64)

    def tables(self):
        return self.btf.tables()

    def params(self):
        return self.btf.params()

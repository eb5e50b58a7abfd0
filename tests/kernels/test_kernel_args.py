"""cl/kernel_args.py ``ArgumentKernel``: a launch that leaves arguments out of ``set_arg``
because they are the objects of the launch before must compute exactly what pyopencl's own
call (every argument set) computes: scalars changed, kept and changed back, a buffer swapped
for another and back."""

from __future__ import annotations

import numpy as np

SOURCE = """
__kernel void affine(const float a, __global const float *x, const float b, const int n,
                     __global float *out)
{
  int i = get_global_id(0);
  if (i < n) {
    out[i] = a * x[i] + b;
  }
}
"""


def test_only_changed_arguments_are_set_and_results_match_a_full_call(cl_context, monkeypatch):
    import pyopencl as cl

    from btf_addon.cl.kernel_args import ArgumentKernel

    ctx, queue = cl_context.context, cl_context.queue
    program = cl.Program(ctx, SOURCE).build()
    mf = cl.mem_flags
    n = 64
    xs = [np.arange(n, dtype=np.float32), np.linspace(-3, 5, n, dtype=np.float32)]
    inputs = [cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=x) for x in xs]
    out = cl.Buffer(ctx, mf.WRITE_ONLY, n * 4)
    kernel = ArgumentKernel(cl.Kernel(program, "affine"))
    set_calls = []
    set_arg = cl.Kernel.set_arg

    def recording_set_arg(self, index, value):
        set_calls.append(index)
        return set_arg(self, index, value)

    monkeypatch.setattr(cl.Kernel, "set_arg", recording_set_arg)

    count = np.int32(n)
    launches = [  # (a, input, b): scalars are the same objects where they repeat
        (np.float32(2.0), 0, np.float32(1.0)),
        (None, 0, None),  # everything as before: nothing set
        (np.float32(-0.5), 0, None),  # only a
        (None, 1, None),  # only the buffer
        (None, 0, np.float32(7.0)),  # the first buffer back, and b
    ]
    a, b = launches[0][0], launches[0][2]
    for step, (new_a, which, new_b) in enumerate(launches):
        a = a if new_a is None else new_a
        b = b if new_b is None else new_b
        set_calls.clear()
        kernel(queue, (n,), None, a, inputs[which], b, count, out)
        host = np.empty(n, np.float32)
        cl.enqueue_copy(queue, host, out)
        np.testing.assert_array_equal(host, np.float32(a) * xs[which] + np.float32(b))
        if step == 0:
            assert set_calls == [0, 1, 2, 3, 4]
        if step == 1:
            assert set_calls == []  # the point: nothing set again
        if step == 2:
            assert set_calls == [0]

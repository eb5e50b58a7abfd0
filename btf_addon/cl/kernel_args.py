"""A kernel launched many times with mostly the same arguments: only the ones that changed are
set again.

pyopencl's ``kernel(queue, size, local, *args)`` sets every argument on every call. The final
render's path tracer takes ~50 (the scene's buffers, the World's tables, the film) of which a
launch changes four or five (its rows, its samples, the adaptive mask): with adaptive sampling
a frame makes a launch every 16 samples or more often, and pyopencl's call took 0.44 ms a
launch where this takes 0.28 with the enqueue (the adaptive demo's F12, profiled).
"""

from __future__ import annotations

from collections.abc import Sequence


class ArgumentKernel:
    """``kernel`` whose arguments are remembered between launches. An argument is set again
    when it is not the very object given last time (identity, not equality: a buffer is the
    same buffer only as the same object, and a fresh scalar is simply set again). The object is
    held until it is replaced, so an identical ``id`` can never belong to another object."""

    def __init__(self, kernel):
        self.kernel = kernel
        self._given: list = []

    def __call__(self, queue, global_size: Sequence[int], local_size: Sequence[int], *args):
        import pyopencl as cl

        # Forgotten until every argument is set: a set_arg that raises leaves nothing to trust.
        given, self._given = self._given, []
        for i, arg in enumerate(args):
            if i >= len(given) or given[i] is not arg:
                self.kernel.set_arg(i, arg)
        self._given = list(args)
        return cl.enqueue_nd_range_kernel(queue, self.kernel, global_size, local_size)

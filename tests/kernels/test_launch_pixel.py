"""kernels/include/btf_launch.h ``launch_pixel``: the permutation that spreads a launch's
work-groups over its band must still give every pixel to exactly one work-item, whatever the
band's shape (one work-group, a prime count, powers of two, widths that do not fill the last
work-group), and must actually spread consecutive work-groups apart (the point of it)."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.cl.programs import KERNELS_DIR

LOCAL_X = 16  # the final render's work-group width (cl/renderer.py LOCAL_SIZE)

KERNEL = """
__kernel void visit(const int width, __global int *visits, __global int *group_of_pixel)
{
  int x, yr;
  launch_pixel(&x, &yr);
  if (x >= width) {
    return;
  }
  atomic_inc(&visits[yr * width + x]);
  group_of_pixel[yr * width + x] = (int)(get_group_id(0) + get_num_groups(0) * get_group_id(1));
}
"""


@pytest.fixture(scope="module")
def visit(cl_context):
    import pyopencl as cl

    header = (KERNELS_DIR / "include" / "btf_launch.h").read_text()
    program = cl.Program(cl_context.context, header + KERNEL).build()
    return cl.Kernel(program, "visit")


@pytest.mark.parametrize(
    ("width", "rows"), [(16, 1), (5, 3), (64, 48), (96, 72), (100, 7), (160, 120), (16, 97)]
)
def test_every_pixel_is_rendered_once(cl_context, visit, width, rows):
    import pyopencl as cl

    ctx, queue = cl_context.context, cl_context.queue
    n = width * rows
    visits = np.zeros(n, np.int32)
    groups = np.full(n, -1, np.int32)
    mf = cl.mem_flags
    visits_buf = cl.Buffer(ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=visits)
    groups_buf = cl.Buffer(ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=groups)
    global_x = -(-width // LOCAL_X) * LOCAL_X
    visit(queue, (global_x, rows), (LOCAL_X, 1), np.int32(width), visits_buf, groups_buf)
    cl.enqueue_copy(queue, visits, visits_buf)
    cl.enqueue_copy(queue, groups, groups_buf)
    np.testing.assert_array_equal(visits, 1)
    if rows >= 8:  # consecutive work-groups land far apart: rows of one run are spread out
        row_of_group = {}
        for pixel, group in enumerate(groups):
            row_of_group.setdefault(int(group), pixel // width)
        first_run = [row_of_group[g] for g in range(min(8, len(row_of_group)))]
        assert max(first_run) - min(first_run) >= rows // 2, first_run

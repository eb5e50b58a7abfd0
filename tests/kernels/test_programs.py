"""Program builds: the packed layout reaches every kernel as -D defines, and compile errors
name the real file and line and are never mistaken for "no OpenCL device"."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.cl import programs
from btf_addon.cl.context import OpenCLUnavailableError
from btf_addon.core.codecs import packed

pytestmark = pytest.mark.opencl


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    """Builds in this test compile for real and leave nothing in the user's cache."""
    monkeypatch.setenv("BTF_CL_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(programs, "_memory_cache", {})


def test_kernels_see_the_python_layout(cl_context, tmp_path, fresh_cache):
    """A kernel that includes btf_packed.h (as every real one does) writes the value of each
    layout macro; they must equal core/codecs/packed.py's definition."""
    import pyopencl as cl

    names = list(packed.defines())
    body = "\n".join(f"  out[{i}] = {name};" for i, name in enumerate(names))
    source = tmp_path / "layout_probe.cl"
    source.write_text(
        f'#include "btf_packed.h"\n__kernel void probe(__global int *out)\n{{\n{body}\n}}\n'
    )
    # An absolute name: KERNELS_DIR / name is then this file, its includes the real headers.
    program = programs.build_program(cl_context.context, cl_context.device, str(source), {})
    out = np.full(len(names), -1, dtype=np.int32)
    buf = cl.Buffer(cl_context.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
    cl.Kernel(program, "probe")(cl_context.queue, (1,), None, buf)
    cl.enqueue_copy(cl_context.queue, out, buf)
    assert dict(zip(names, out.tolist(), strict=True)) == packed.defines()


def test_the_real_kernels_refuse_to_build_without_the_layout(cl_context):
    """btf_packed.h writes no slot number, so a build that bypasses build_program fails loudly
    (its #error) instead of reading the wrong slots."""
    import pyopencl as cl

    source = programs.expand_includes(programs.KERNELS_DIR / "btf_eval.cl")
    unbuilt = cl.Program(cl_context.context, source)
    with pytest.raises(cl.RuntimeError):
        unbuilt.build(devices=[cl_context.device])
    log = unbuilt.get_build_info(cl_context.device, cl.program_build_info.LOG)
    assert "packed-layout defines missing" in log


def test_a_variant_may_not_redefine_the_layout(cl_context):
    with pytest.raises(ValueError, match="H_CODEC"):
        programs.build_program(cl_context.context, cl_context.device, "btf_eval.cl", {"H_CODEC": 2})


def _broken_tree(tmp_path):
    kernels = tmp_path / "kernels"
    (kernels / "include").mkdir(parents=True)
    (kernels / "include" / "helper.h").write_text(
        "/* line 1 */\n"
        "inline float helper(float x)\n"  # line 2
        "{\n"
        "  return x * undeclared_in_header;\n"  # line 4
        "}\n"
    )
    (kernels / "include" / "fine.h").write_text("inline float fine(float x) { return x; }\n")
    (kernels / "broken.cl").write_text(
        '#include "fine.h"\n'  # line 1
        "\n"
        "__kernel void k(__global float *out)\n"  # line 3
        "{\n"
        "  out[0] = fine(1.0f) + undeclared_in_kernel;\n"  # line 5
        "}\n"
    )
    (kernels / "header_broken.cl").write_text(
        '#include "fine.h"\n#include "helper.h"\n'
        "__kernel void k(__global float *out) { out[0] = helper(1.0f); }\n"
    )
    return kernels


@pytest.mark.parametrize(
    ("kernel", "where", "symbol"),
    [
        ("broken.cl", "kernels/broken.cl:5", "undeclared_in_kernel"),
        ("header_broken.cl", "kernels/include/helper.h:4", "undeclared_in_header"),
    ],
)
def test_compile_errors_name_the_real_file_and_line(
    cl_context, tmp_path, monkeypatch, fresh_cache, kernel, where, symbol
):
    """The #line directives expand_includes writes make the log point at the file a developer
    edits, not at line 300 of the expanded text; the error is OpenCLCompileError, never
    OpenCLUnavailableError (a broken kernel is a bug to fix, not a missing driver)."""
    monkeypatch.setattr(programs, "KERNELS_DIR", _broken_tree(tmp_path))
    with pytest.raises(programs.OpenCLCompileError) as caught:
        programs.build_program(cl_context.context, cl_context.device, kernel, {})
    err = caught.value
    assert not isinstance(err, OpenCLUnavailableError)
    assert err.kernel == f"kernels/{kernel}"
    assert where in err.build_log, err.build_log
    assert symbol in err.build_log
    assert where in str(err)  # the message carries the log


def test_expanded_source_maps_every_line_back():
    """Each line of the expanded btf_eval.cl sits under a #line naming its file, at its line."""
    text = programs.expand_includes(programs.KERNELS_DIR / "btf_eval.cl")
    files, current, number = {}, None, 0
    for line in text.splitlines():
        if line.startswith("#line "):
            _, n, name = line.split(" ", 2)
            current, number = name.strip('"'), int(n)
            continue
        source = (programs.KERNELS_DIR.parent / current).read_text().splitlines()
        assert source[number - 1] == line, (current, number)
        files[current] = files.get(current, 0) + 1
        number += 1
    assert {"kernels/btf_eval.cl", "kernels/include/btf_packed.h"} <= set(files)

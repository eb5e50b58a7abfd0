"""Helpers shared by the tests: data locations, skips that state their reason, sampling."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
SHARED_BTFBASE = ROOT.parent / "shared" / "data" / "btfbase"
MATERIALS = ("alu", "wallpaper")


def shared_material(name: str) -> Path:
    path = SHARED_BTFBASE / name
    if not (path / "all_materialInfo.txt").is_file():
        pytest.skip(
            f"real BTFbase data not found at {path}: it ships in ../shared beside CI's "
            "clone, not in a user's clone"
        )
    return path


def studiolights_dir() -> Path:
    """Blender's bundled HDR environments, found without importing bpy."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        pytest.skip("the bpy module (which ships the studiolight EXRs) is not installed")
    bpy_dir = Path(next(iter(spec.submodule_search_locations)))
    found = sorted(bpy_dir.glob("*/datafiles/studiolights/world"))
    if not found:
        pytest.skip(f"no studiolights inside {bpy_dir}")
    return found[-1]


def random_hemisphere(rng: np.random.Generator, n: int) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def cli_env(**overrides: str) -> dict[str, str]:
    """Environment for a CLI subprocess: this checkout importable from any folder, and not the
    isolated Blender user folder that tests/blender sets for this process (a subprocess would
    otherwise load the installed extension's bundled wheels ahead of the venv's packages)."""
    import os

    env = {k: v for k, v in os.environ.items() if k != "BLENDER_USER_RESOURCES"}
    env["PYTHONPATH"] = str(ROOT)
    env.update(overrides)
    return env


def venv_opencl_vendors(folder: Path) -> dict[str, str]:
    """Environment for a Blender subprocess whose extension brings its own pyopencl: an ICD
    folder in ``folder`` registering this venv's OpenCL drivers by absolute path, as a
    machine's system-wide registration (/etc/OpenCL/vendors) does. pocl-binary-distribution
    registers PoCL only inside the venv's pyopencl, by a bare library name that another
    pyopencl's loader cannot resolve. The system's own registrations are kept beside it
    (OCL_ICD_VENDORS replaces /etc/OpenCL/vendors): on a CPU newer than the bundled PoCL's
    LLVM only a system driver builds. Empty where there is neither."""
    spec = importlib.util.find_spec("pyopencl")
    folder.mkdir(parents=True, exist_ok=True)
    found = False
    if spec is not None and spec.origin is not None:
        libs = Path(spec.origin).parent / ".libs"
        for icd in sorted(libs.glob("*.icd")):
            (folder / f"venv-{icd.name}").write_text(str(libs / icd.read_text().strip()) + "\n")
            found = True
    for icd in sorted(Path("/etc/OpenCL/vendors").glob("*.icd")):
        (folder / f"system-{icd.name}").write_text(icd.read_text())
        found = True
    return {"OCL_ICD_VENDORS": str(folder)} if found else {}


def random_queries(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 6) uniform queries: u, v in [0, 1), θ in [0, 90°), φ in [0, 360°)."""
    return np.column_stack(
        [
            rng.random(n),
            rng.random(n),
            rng.random(n) * 90,
            rng.random(n) * 360,
            rng.random(n) * 90,
            rng.random(n) * 360,
        ]
    )


def run_python(*args, check=True, cwd=ROOT, env=None) -> subprocess.CompletedProcess:
    """This venv's Python in a subprocess (``-m btf_addon …`` or ``-c CODE``), with this
    checkout importable; ``check`` asserts exit code 0 and shows stderr otherwise."""
    proc = subprocess.run(
        [sys.executable, *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
        env=env or cli_env(),
    )
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def run_cli(*args, check=True, cwd=ROOT, env=None) -> subprocess.CompletedProcess:
    """``python -m btf_addon ARGS`` in a subprocess."""
    return run_python("-m", "btf_addon", *args, check=check, cwd=cwd, env=env)


def make_blend(path, script: str) -> None:
    """Build a .blend in a separate Blender process (a test process must not import bpy, or,
    under tests/blender, has the installed extension registered): ``script`` runs with
    ``bpy``, ``scene`` and this checkout's add-on registered, then the file is saved."""
    import textwrap

    code = (
        textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        import bpy
        import btf_addon
        from btf_addon.blender.compat import with_nodes  # new materials/worlds with nodes
        bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
        btf_addon.register()
        scene = bpy.context.scene
    """)
        + textwrap.dedent(script)
        + f"\nbpy.ops.wm.save_as_mainfile(filepath={str(path)!r})\n"
        + "from btf_addon.blender.compat import exit_python\nexit_python(0)\n"
    )
    run_python("-c", code)


def read_png(path) -> np.ndarray:
    """An 8-bit, non-interlaced RGB or RGBA PNG → (H, W, channels) uint8, row 0 at the top:
    enough to read back what Blender and ``core.formats.imageio.write_png`` save, without Pillow."""
    import struct
    import zlib

    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path}: not a PNG"
    pos, idat, header = 8, [], None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    assert depth == 8 and colour in (2, 6) and interlace == 0, header
    channels = 3 if colour == 2 else 4
    stride = width * channels
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), np.uint8).reshape(height, stride + 1)
    out = np.zeros((height, stride), np.int32)
    previous = np.zeros(stride, np.int32)
    for y in range(height):  # undo the per-row filters (PNG spec, section 9)
        kind, row = raw[y, 0], raw[y, 1:].astype(np.int32)
        if kind == 0:
            line = row
        elif kind == 2:
            line = (row + previous) & 255
        else:
            line = np.zeros(stride, np.int32)
            for x in range(stride):
                left = line[x - channels] if x >= channels else 0
                up_left = previous[x - channels] if x >= channels else 0
                if kind == 1:
                    predictor = left
                elif kind == 3:
                    predictor = (left + previous[x]) // 2
                else:  # 4: Paeth
                    p = left + previous[x] - up_left
                    pa, pb, pc = abs(p - left), abs(p - previous[x]), abs(p - up_left)
                    predictor = (
                        left if pa <= pb and pa <= pc else previous[x] if pb <= pc else up_left
                    )
                line[x] = (row[x] + predictor) & 255
        out[y] = previous = line
    return out.reshape(height, width, channels).astype(np.uint8)


# --- mapping (tests/gl/test_mapping_render.py, tests/kernels/test_mapping_kernel.py) ----------
def stripe_btf(tile_mm: float):
    """A dense BTF of 8 × 1 texels, half dark and half bright, the same at every angle: one
    stripe period per tile along u, and a tile of ``tile_mm`` square."""
    from btf_addon.core.codecs.dense import DenseBTF
    from btf_addon.core.grid import RingGrid

    image = np.zeros((1, 8, 3), dtype=np.float32)
    image[:, :4] = 0.1
    image[:, 4:] = 0.9
    flat = RingGrid((0.0,), (1,))
    return DenseBTF(image[None, None], flat, flat, tile_size_mm=(tile_mm, tile_mm))


def count_periods(row: np.ndarray) -> int:
    """Dominant number of periods along a 1D signal (its strongest non-DC frequency)."""
    spectrum = np.abs(np.fft.rfft(row - row.mean()))
    return int(np.argmax(spectrum[1:]) + 1)


def building_device_indices() -> list[int]:
    """Indices (``list_devices()`` order) of this machine's OpenCL devices that build programs:
    what the tests that loop over every device loop over. A device that cannot build (the
    bundled PoCL on a CPU newer than its LLVM) is no render target; its verdict and reason
    are the doctor's to report (tests/kernels/test_device_choice.py)."""
    from btf_addon.cl.devices import OpenCLUnavailableError, device_report

    try:
        return [row["index"] for row in device_report() if row["builds"]]
    except OpenCLUnavailableError:
        return []


def sphere_with_checked_mean(cl_context, env, btf):
    """A CLRenderer of a unit sphere of ``btf`` under ``env`` (48 × 36, pixel centres, a fixed
    launch split), after checking its Sampled mean (2048 samples) within 0.5 % of 16384
    virtual lights drawn from the plain tables: an independent estimate, the bound of the MIS
    test in test_render_direct.py."""
    from btf_addon.cl.renderer import CLRenderer
    from btf_addon.scene.primitives import uv_sphere
    from btf_addon.scene.scene import Camera, Material, Scene, look_at

    camera = Camera(look_at((0.0, -4.0, 1.0), (0, 0, 0)))
    scene = Scene([uv_sphere(1.0, segments=96, rings=48)], [Material(btf)], camera, env)
    renderer = CLRenderer(scene, 48, 36, cl_context, film=None)
    renderer.fixed_launch_split = True
    virtual = renderer.render_direct(env.virtual_lights(16384)).combined[..., :3]
    sampled = renderer.render_sampled(2048, seed=5)[..., :3]
    np.testing.assert_allclose(sampled.mean(axis=(0, 1)), virtual.mean(axis=(0, 1)), rtol=0.005)
    return renderer


def errors_on_and_off(renderer, reference, flag: str) -> dict[bool, float]:
    """{True: e, False: e}: the mean relative RMSE against ``reference`` of three 64-sample
    renders (seeds 1-3) with the renderer's boolean attribute ``flag`` on, then off (it is
    left off). The A/B of a sampling strategy in test_mis_compensation, test_sun_sampling and
    test_lobe_window."""
    from cycles_scenes import relative_rmse

    errors = {}
    for on in (True, False):
        setattr(renderer, flag, on)
        images = [renderer.render_sampled(64, seed=s)[..., :3] for s in (1, 2, 3)]
        errors[on] = float(np.mean([relative_rmse(image, reference) for image in images]))
    return errors


def render_program_with(cl_context, test_kernels: str):
    """The final render's real program (kernels/render_direct.cl with its includes, built with
    the renderer's defines for a scene with shadows and an environment texture: program_defines
    passes BAKE_BIN_MARGIN_PERMILLE too) with ``test_kernels`` appended, which call its inline
    functions."""
    import pyopencl as cl

    from btf_addon.cl.programs import KERNELS_DIR, build_defines, expand_includes
    from btf_addon.cl.renderer import program_defines
    from btf_addon.scene.analysis import SceneFeatures

    features = SceneFeatures(shadows=True, environment_texture=True)
    text = expand_includes(KERNELS_DIR / "render_direct.cl") + "\n" + test_kernels
    options = [f"-D{k}={v}" for k, v in sorted(build_defines(program_defines(features)).items())]
    return cl.Program(cl_context.context, text).build(options)


def run_kernel(cl_context, kernel, n: int, inputs, outputs) -> None:
    """Launch ``kernel`` over ``n`` work-items: numpy ``inputs`` become read-only buffers
    (scalars pass as they are), then one write-only buffer per array of ``outputs``, which are
    filled from them."""
    import pyopencl as cl

    mf = cl.mem_flags
    ctx, queue = cl_context.context, cl_context.queue
    args = []
    for value in inputs:
        if isinstance(value, np.ndarray):
            value = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=value)
        args.append(value)
    out_bufs = [cl.Buffer(ctx, mf.WRITE_ONLY, out.nbytes) for out in outputs]
    kernel(queue, (n,), None, *args, *out_bufs)
    for out, buf in zip(outputs, out_bufs, strict=True):
        cl.enqueue_copy(queue, out, buf)

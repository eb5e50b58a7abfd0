"""``python -m btf_addon bridge`` in a subprocess against the OpenXR test runtime: output,
captures, and the exit codes of the faults (messages without tracebacks)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from helpers import cli_env, make_blend, run_cli

from btf_addon.core.colour import srgb_encode
from btf_addon.core.formats.imageio import read_exr

# sRGB 8-bit quantisation of the submitted image (tests/xr/test_bridge.py says why).
SRGB_TOLERANCE = 1.0 / 255 + 1e-6


@pytest.fixture(scope="module")
def blend(tmp_path_factory):
    """A sphere (a plain material: drawn in its analytic look) 4 m in front of the camera,
    under a grey World."""
    path = tmp_path_factory.mktemp("bridge_blend") / "sphere.blend"
    make_blend(
        path,
        """
        import math
        bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, location=(0.0, 0.0, 0.0))
        cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
        scene.collection.objects.link(cam)
        cam.location = (0.0, -4.0, 0.3)
        cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
        scene.camera = cam
        world = with_nodes(bpy.data.worlds.new("W"))
        world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.6, 0.6, 0.6, 1.0)
        scene.world = world
        """,
    )
    return path


# The head at the .blend's camera, turned +90° about x: looking along +Y at the sphere (poses
# are scene coordinates under the default --place space).
HEAD = [0.0, -4.0, 0.3, math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4)]


def script(xr_runtime, **overrides):
    values = {"eye_size": [40, 30], "display_period_s": 0.01, "head": [HEAD]}
    values.update(overrides)
    return xr_runtime.script(**values)


def test_bridge_runs_frames_prints_what_it_used_and_captures(xr_runtime, blend, tmp_path):
    script(xr_runtime, strict_teardown="log")  # the runtime logs any teardown Monado crashed on
    cap = tmp_path / "cap"
    proc = run_cli(
        "bridge", "--blend", blend, "--frames", "6", "--capture", cap, "--converge",
        "--lights", "8", env=cli_env(),
    )  # fmt: skip
    out = proc.stdout
    assert "strict teardown" not in proc.stderr, proc.stderr
    assert "runtime: BTF test runtime" in out
    # Why the start and the first frames took what they took (issue 30 item 7).
    assert "warm-up: start: " in out and "OpenXR session and GL context" in out
    assert "warm-up: frame 1: " in out
    assert "values from: runtime" in out
    assert "eye size: 40x30; frames: 6" in out and "FPS:" in out
    assert "left eye:" in out and "lights per frame" in out
    frames = xr_runtime.captured()
    assert len(frames) == 6
    for n, frame in enumerate(frames):
        for view, eye in zip(frame.views, ("left", "right"), strict=True):
            meta = json.loads((cap / f"frame_{n:05d}_{eye}.json").read_text())
            assert meta["pose"] == pytest.approx(view.pose, abs=1e-6)
            assert meta["fov"] == pytest.approx(view.fov, abs=1e-6)
            assert meta["lights_total"] == 8 and meta["eye_size"] == [40, 30]
            image = read_exr(cap / meta["image"])[::-1]  # row 0 at the bottom, as submitted
            a = srgb_encode(np.clip(image, 0, 1))
            b = srgb_encode(np.clip(view.image[..., :3], 0, 1))
            assert np.abs(a - b).max() <= SRGB_TOLERANCE
    # The sphere is in view: a grey World around a shaded ball, not a uniform image.
    assert read_exr(cap / "frame_00005_left.exr").std() > 0.02
    # The head is still and --converge holds it: the lights accumulate frame after frame.
    done = [
        json.loads((cap / f"frame_{n:05d}_left.json").read_text())["lights_done"] for n in range(6)
    ]
    assert done == sorted(done) and done[0] < done[-1] <= 8, done


@pytest.mark.parametrize(
    ("overrides", "code", "words"),
    [
        ({"system_available": False}, 4, "no head-mounted display"),
        ({"lose_session_after_frames": 2}, 5, "lost the session"),
        ({"views": 3}, 6, "3 views"),
        ({"formats": [0x81A6]}, 6, "no swapchain format"),
        ({"extensions": ["XR_KHR_opengl_enable"]}, 6, "XR_MNDX_egl_enable"),
    ],
)
def test_bridge_exit_codes(xr_runtime, blend, overrides, code, words):
    script(xr_runtime, **overrides)
    # No X display: a runtime without the EGL binding is refused, not tried through GLX.
    env = cli_env(DISPLAY="")
    proc = run_cli("bridge", "--blend", blend, "--frames", "5", check=False, env=env)
    assert proc.returncode == code, proc.stderr
    assert words in proc.stderr and "Traceback" not in proc.stderr


def test_bridge_without_a_runtime(blend, tmp_path):
    missing = tmp_path / "nothing.json"
    proc = run_cli(
        "bridge", "--blend", blend, "--frames", "1", check=False,
        env=cli_env(XR_RUNTIME_JSON=str(missing)),
    )  # fmt: skip
    assert proc.returncode == 3
    assert f"XR_RUNTIME_JSON={missing} (does not exist)" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_bridge_usage_errors(tmp_path):
    proc = run_cli("bridge", "--blend", tmp_path / "none.blend", check=False)
    assert proc.returncode == 2 and "no such .blend" in proc.stderr
    proc = run_cli("bridge", "--blend", tmp_path / "x.blend", "--frames", "0", check=False)
    assert proc.returncode == 2 and "must be at least 1" in proc.stderr


def test_bridge_with_a_manifest_naming_a_missing_library(blend, tmp_path):
    """The manifest exists but the runtime library it names does not (issue 30 item 7): the
    message names the library, resolved against the manifest's folder as the loader does."""
    manifest = tmp_path / "runtime.json"
    manifest.write_text(
        '{"file_format_version": "1.0.0", "runtime": {"library_path": "./gone/libruntime.so"}}'
    )
    proc = run_cli(
        "bridge", "--blend", blend, "--frames", "1", check=False,
        env=cli_env(XR_RUNTIME_JSON=str(manifest)),
    )  # fmt: skip
    assert proc.returncode == 3, proc.stderr
    library = tmp_path / "gone" / "libruntime.so"
    assert f"the runtime library it names, {library}, does not exist" in proc.stderr
    assert "does not exist" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize("signum", ["SIGINT", "SIGTERM"])
def test_ctrl_c_in_the_frame_loop_exits_130_and_ends_the_session(xr_runtime, blend, signum):
    """The real CLI process, no --frames: a signal once frames flow ends it with 130 and one
    line, after ending the frame and the session in the order the spec allows (the runtime's
    strict teardown would abort the process otherwise: issue 30 item 1)."""
    import signal
    import subprocess
    import sys
    import time

    from helpers import ROOT

    script(xr_runtime, strict_teardown=True, head_motion=[0.002, 0.002], pace=True)
    proc = subprocess.Popen(
        [sys.executable, "-m", "btf_addon", "bridge", "--blend", str(blend), "--hud"],
        cwd=ROOT, env=cli_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while len(xr_runtime.captured()) < 3 and proc.poll() is None:
            assert time.monotonic() < deadline, "no frames within 120 s"
            time.sleep(0.05)
        proc.send_signal(getattr(signal, signum))
        _out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, err
    what = "interrupted" if signum == "SIGINT" else "terminated"
    assert f"{what}: stopped" in err and "Traceback" not in err
    assert "strict teardown" not in err

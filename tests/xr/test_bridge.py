"""The XTAL bridge (btf_addon/xr/) against the OpenXR test runtime through the real loader
(fixtures in tests/xr/conftest.py): the session's life, the submitted images against an
independent render of the submitted poses, captures, and the faults' errors.

Eye sizes stay small (48×36): llvmpipe costs about 1 µs per pixel·light.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.colour import srgb_encode
from btf_addon.core.sampling.envmap import Environment
from btf_addon.render.headsets import EyeFov, projection_from_fov
from btf_addon.render.settings import RenderSettings
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

EYE = (48, 36)
CAMERA_AT = np.array([0.0, -4.0, 0.3])
STANDING = [0.0, 1.6, 0.0]  # a head in a real runtime's +y-up space ("camera" placement)
IPD = 0.064
FOV_LEFT = [-0.80, 0.70, 0.78, -0.78]
FOV_RIGHT = [-0.70, 0.80, 0.78, -0.78]
# sRGB 8-bit quantisation: the submitted image holds round(255·encode(x)); our float render
# encoded the same way differs by at most half a step from the stored value, plus float
# accumulation order (batches of K vs one batch: ~1e-6 relative) → 1/255 covers both.
SRGB_TOLERANCE = 1.0 / 255 + 1e-6


def small_scene(rng) -> Scene:
    """A GGX sphere on a Lambertian floor under a random environment, the camera 4 m back
    looking along +Y (heading 0)."""
    floor = plane(6.0, uv_repeats=3.0, material=1)
    floor.world_from_object = np.eye(4)
    floor.world_from_object[2, 3] = -1.0
    return Scene(
        [uv_sphere(1.0, segments=24, rings=12), floor],
        [Material(GGXBTF((0.9, 0.6, 0.3), 0.35)), Material(LambertianBTF(0.5))],
        Camera(
            look_at(CAMERA_AT, CAMERA_AT + np.array([0.0, 1.0, 0.0])),
            clip_start=0.05,
            clip_end=50.0,
        ),
        Environment(rng.gamma(0.7, 1.0, size=(16, 32, 3))),
    )


def quat_mul(a, b) -> list[float]:
    """Hamilton product of quaternions (x, y, z, w): the rotation b, then a."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]


def head(dx: float = 0.0, yaw: float = 0.0, placement: str = "space") -> list[float]:
    """A head pose [x, y, z, qx, qy, qz, qw], ``dx`` metres right and turned ``yaw`` radians
    left of looking at the sphere. "space": in the scene's own coordinates (+z up): at the
    scene camera, turned +90° about x so that its −z looks along +Y. "camera": standing in a
    +y-up space looking down −z, as a real runtime reports a head."""
    half = yaw / 2
    if placement == "space":
        upright = [math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4)]
        q = quat_mul([0.0, 0.0, math.sin(half), math.cos(half)], upright)
        return [CAMERA_AT[0] + dx, CAMERA_AT[1], CAMERA_AT[2], *q]
    return [STANDING[0] + dx, STANDING[1], STANDING[2], 0.0, math.sin(half), 0.0, math.cos(half)]


@pytest.fixture(autouse=True)
def clean_teardown(capfd):
    """Every bridge run here ends in the order the spec allows: the test runtime logs each
    teardown hazard Monado crashed on ("strict_teardown": "log", set by ``script``), and
    none may appear (tests/xr/test_bridge_interrupts.py makes them fatal)."""
    yield
    err = capfd.readouterr().err
    assert "strict teardown" not in err, err


def script(xr_runtime, **overrides):
    values = {
        "strict_teardown": "log",
        "eye_size": list(EYE),
        "ipd": IPD,
        "fov": {"left": FOV_LEFT, "right": FOV_RIGHT},
        "display_period_s": 0.01,
        "head": [head()],
    }
    values.update(overrides)
    return xr_runtime.script(**values)


def settings(**kw):
    from btf_addon.xr.bridge import BridgeSettings

    kw.setdefault("show_hud", False)
    kw.setdefault("lights_total", 8)
    return BridgeSettings(**kw)


# --- an independent render, not the bridge's code path -----------------------------------
def rotation(q) -> np.ndarray:
    """Unit quaternion (x, y, z, w) → (3, 3) rotation (the textbook formula)."""
    x, y, z, w = q
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


def world_from_eye(pose, placement: str, first_head) -> np.ndarray:
    """Where the bridge's documentation says an eye is. "space": the pose as it is.
    "camera": the runtime's space turned +y-up → +z-up, the first head position moved onto
    the scene camera (heading 0 here)."""
    eye_in_space = np.eye(4)
    eye_in_space[:3, :3] = rotation(pose[3:])
    eye_in_space[:3, 3] = pose[:3]
    if placement == "space":
        return eye_in_space
    eye_in_space[:3, 3] -= first_head
    zup = np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], dtype=float)
    to_camera = np.eye(4)
    to_camera[:3, 3] = CAMERA_AT
    return to_camera @ zup @ eye_in_space


def independent_render(
    gl_ctx, scene, pose, fov, lights_total, placement="space", first_head=None
) -> np.ndarray:
    """(h, w, 3) float32 linear, row 0 at the bottom: all lights at once."""
    from btf_addon.gl.drawer import ProgressiveDrawer, ViewAccumulation
    from btf_addon.gl.moderngl_device import ModernGLDevice

    world_from_view = world_from_eye(pose, placement, first_head)
    clip_from_view = projection_from_fov(EyeFov(*fov), scene.camera.clip_start, 50.0)
    device = ModernGLDevice(gl_ctx)
    drawer = ProgressiveDrawer(device, scene)
    view = ViewAccumulation(device, *EYE)
    try:
        view.set_lights(scene.environment.virtual_lights(lights_total, seed=0), lights_total)
        drawer.restart(
            view, clip_from_view @ np.linalg.inv(world_from_view), [*world_from_view[:3, 3], 1]
        )
        while drawer.add_batch(view):
            pass
        drawer.resolve(view)
        return view.read()[..., :3]
    finally:
        view.release()
        drawer.release()
        device.close()


def encoded(image) -> np.ndarray:
    return srgb_encode(np.clip(np.asarray(image, dtype=np.float64), 0.0, 1.0))


# --- the session ----------------------------------------------------------------------------
def test_session_reaches_focused_submits_stereo_frames_and_ends_cleanly(xr_runtime, rng):
    from btf_addon.xr.bridge import XRBridge

    script(xr_runtime)
    bridge = XRBridge(small_scene(rng), RenderSettings(), settings())
    bridge.start()
    states = []
    try:
        while bridge.run_frame():
            states.append(bridge.status.state)
            if bridge.frames >= 5:
                bridge.request_stop()
        assert len(states) < 200, "the runtime never ended the session"
    finally:
        bridge.close()
    assert "FOCUSED" in states
    assert bridge.status.state == "ended"
    assert bridge.status.runtime == "BTF test runtime"
    assert bridge.status.eye_size == EYE
    assert bridge.status.values_from == "runtime"
    frames = xr_runtime.captured()
    assert len(frames) == 5
    for frame in frames:
        assert len(frame.views) == 2
        for view in frame.views:
            assert view.image.shape == (EYE[1], EYE[0], 4)
            assert view.format == 0x8C43  # GL_SRGB8_ALPHA8: the preferred format, offered first
    # Poses as submitted: the located ones (no --converge), the eyes IPD apart.
    left, right = frames[0].views[0].pose, frames[0].views[1].pose
    assert np.linalg.norm(np.subtract(left[:3], right[:3])) == pytest.approx(IPD, abs=1e-6)
    assert frames[0].views[0].fov == pytest.approx(FOV_LEFT, abs=1e-6)
    assert frames[0].views[1].fov == pytest.approx(FOV_RIGHT, abs=1e-6)


@pytest.mark.parametrize("placement", ["space", "camera"])
def test_submitted_images_equal_an_independent_render_of_the_submitted_poses(
    xr_runtime, rng, gl_ctx, placement
):
    """--converge: the first located pose is held for the whole run while the head moves in
    the script; by the last frame all 8 lights are in, and each eye equals a render of that
    pose with all lights at once (placed in the scene as the documentation says), within sRGB
    8-bit quantisation."""
    from btf_addon.xr.bridge import run_bridge

    path = [head(0.01 * i, 0.02 * i, placement) for i in range(12)]
    script(xr_runtime, head=path)
    scene = small_scene(rng)
    # A large budget: K grows every frame, so 8 lights are in within a few frames.
    run_bridge(
        scene,
        RenderSettings(use_antialiasing=False),  # the reference is drawn at pixel centres
        settings(converge=True, budget_s=10.0, placement=placement),
        frames=8,
    )
    frames = xr_runtime.captured()
    assert len(frames) == 8
    for frame in frames:  # the first located pose, held for the whole run
        for view, first in zip(frame.views, frames[0].views, strict=True):
            assert view.pose == pytest.approx(first.pose)
    # The script's head moved: the runtime located other poses than the held one.
    assert frames[-1].views[0].located_pose != pytest.approx(frames[0].views[0].pose)
    held = frames
    converged = held[-1]
    for view in converged.views:
        ours = independent_render(
            gl_ctx, scene, view.pose, view.fov, 8, placement, np.array(STANDING)
        )
        diff = np.abs(encoded(view.image[..., :3]) - encoded(ours))
        assert diff.max() <= SRGB_TOLERANCE, diff.max()
        assert ours.mean() > 0.02  # the sphere and floor are in view, not a black frame


def read_eye(json_path):
    """A capture's JSON (xr/capture.py) and its image ((h, w, 3) float32, row 0 at the top)."""
    import json

    from btf_addon.core.formats.imageio import read_exr

    meta = json.loads(json_path.read_text())
    return meta, read_exr(json_path.parent / meta["image"])


def test_captures_agree_with_the_submitted_frames(xr_runtime, rng, tmp_path):
    from btf_addon.xr.bridge import run_bridge

    script(xr_runtime, head=[head(0.02 * i) for i in range(6)])
    run_bridge(
        small_scene(rng),
        RenderSettings(),
        # No HUD: its translucent panel is blended over the float image in the capture but
        # over the 8-bit (clamped) one in the swapchain, so they differ under it where the
        # scene is brighter than 1 (docs/user-guide.md says so).
        settings(capture_dir=tmp_path / "cap", exposure=0.5),
        frames=4,
    )
    frames = xr_runtime.captured()
    assert len(frames) == 4
    done = []
    for n, frame in enumerate(frames):
        for view, eye in zip(frame.views, ("left", "right"), strict=True):
            meta, image = read_eye(tmp_path / "cap" / f"frame_{n:05d}_{eye}.json")
            assert meta["runtime"] == "BTF test runtime"
            assert meta["pose"] == pytest.approx(view.pose, abs=1e-6)
            assert meta["fov"] == pytest.approx(view.fov, abs=1e-6)
            assert meta["eye_size"] == list(EYE)
            assert meta["exposure"] == 0.5
            # The EXR (row 0 at the top) is the linear image the swapchain got.
            diff = np.abs(encoded(image[::-1]) - encoded(view.image[..., :3]))
            assert diff.max() <= SRGB_TOLERANCE, diff.max()
            if eye == "left":
                done.append(meta["lights_done"])
    # Each eye moves every frame here, so each frame restarts: the lights of that frame only.
    assert all(1 <= d <= 8 for d in done)


def test_request_stop_and_status_from_another_thread(xr_runtime, rng):
    """The operator's pattern: the frame loop on a worker thread, status/stop from another."""
    from btf_addon.controllers import actions, xr_bindings
    from btf_addon.xr.bridge import ControlMap, XRBridge

    script(xr_runtime)
    controls = ControlMap(
        xr_bindings.ACTION_SET, xr_bindings.XR_ACTIONS, actions.Edit, actions.CONTINUOUS
    )
    bridge = XRBridge(small_scene(rng), RenderSettings(), settings(), controls)
    errors, seen, attached = [], [], []

    def loop():
        try:
            bridge.start()
            attached.append(bridge.controls is not None and bool(bridge.controls.profiles))
            while bridge.run_frame():
                pass
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)
        finally:
            bridge.close()

    worker = threading.Thread(target=loop)
    worker.start()
    for _ in range(2000):
        seen.append(bridge.status.frames)
        if bridge.status.frames >= 3:
            break
        threading.Event().wait(0.01)
    bridge.set_scene(small_scene(np.random.default_rng(1)))
    bridge.request_stop()
    worker.join(timeout=120)
    assert not worker.is_alive() and not errors, errors
    assert max(seen) >= 3
    assert bridge.status.state == "ended"
    # The action set was made, bindings suggested and attached; the test runtime's
    # controllers report inactive states, so no edits.
    assert attached == [True] and bridge.status.message == ""
    assert bridge.pop_edits() == []


# --- faults ---------------------------------------------------------------------------------
def test_no_runtime(monkeypatch, rng, tmp_path):
    from btf_addon.xr.bridge import NoRuntimeError, run_bridge

    missing = tmp_path / "missing_runtime.json"
    monkeypatch.setenv("XR_RUNTIME_JSON", str(missing))
    with pytest.raises(NoRuntimeError) as info:
        run_bridge(small_scene(rng), RenderSettings(), settings(), frames=1)
    assert info.value.exit_code == 3
    assert str(missing) in str(info.value) and "does not exist" in str(info.value)


@pytest.mark.parametrize(
    ("overrides", "error", "code", "words"),
    [
        ({"system_available": False}, "NoHeadsetError", 4, "no head-mounted display"),
        ({"views": 3}, "UnsupportedRuntimeError", 6, "3 views"),
        ({"formats": [0x81A6]}, "UnsupportedRuntimeError", 6, "no swapchain format"),
    ],
)
def test_runtime_faults_give_clear_errors(xr_runtime, rng, overrides, error, code, words):
    """(A runtime without XR_MNDX_egl_enable is tested through the CLI, in a process of its
    own: the loader keeps the first extension list it read in a process.)"""
    from btf_addon.xr import bridge as bridge_module

    script(xr_runtime, **overrides)
    with pytest.raises(bridge_module.BridgeError) as info:
        bridge_module.run_bridge(small_scene(rng), RenderSettings(), settings(), frames=2)
    assert type(info.value).__name__ == error
    assert info.value.exit_code == code
    assert words in str(info.value)


def test_session_lost_mid_run(xr_runtime, rng):
    from btf_addon.xr.bridge import SessionLostError, run_bridge

    script(xr_runtime, lose_session_after_frames=3)
    with pytest.raises(SessionLostError) as info:
        run_bridge(small_scene(rng), RenderSettings(), settings(), frames=10)
    assert info.value.exit_code == 5
    assert "lost the session" in str(info.value)
    assert len(xr_runtime.captured()) == 3


@pytest.mark.parametrize(("fmt", "name"), [(0x881A, "RGBA16F"), (0x8058, "RGBA8")])
def test_linear_swapchain_formats_get_linear_values(xr_runtime, rng, gl_ctx, fmt, name):
    """Without sRGB formats the bridge writes linear values (what the runtime reads from a
    UNORM/float image); RGBA8's step is 1/255 in linear terms, RGBA16F's far finer."""
    from btf_addon.xr.bridge import run_bridge

    script(xr_runtime, formats=[fmt])
    scene = small_scene(rng)
    plain = RenderSettings(use_antialiasing=False)  # the reference is drawn at pixel centres
    run_bridge(scene, plain, settings(converge=True, budget_s=10.0), frames=8)
    view = xr_runtime.captured()[-1].views[0]  # the held pose, all lights in by now
    assert view.format == fmt, name
    ours = independent_render(gl_ctx, scene, view.pose, view.fov, 8)
    if fmt == 0x8058:  # UNORM: clamped to [0, 1], half a step of rounding
        assert np.abs(np.clip(ours, 0, 1) - view.image[..., :3]).max() <= 0.5 / 255 + 1e-6
    else:  # half float: 11 significant bits; one ulp (2^-10 ≈ 9.8e-4 relative) covers
        # rounding either way (llvmpipe's conversion truncates)
        assert np.allclose(view.image[..., :3], ours, rtol=2.0**-10, atol=1e-6)


def test_the_hud_floats_below_the_view_in_both_eyes(xr_runtime, rng):
    """With the HUD, each eye shows its panel below the centre (0.25 m under the eye line at
    1.2 m: its top edge at tan = −0.146, row 15 of 36 with these FOVs) and nothing changes in
    the top half."""
    from btf_addon.xr.bridge import run_bridge

    scene = small_scene(rng)
    images = {}
    for hud in (False, True):
        script(xr_runtime, capture_dir=str(xr_runtime.dir / f"hud_{hud}"))
        # One light: both runs hold the same image whatever K the budget picks.
        run_bridge(scene, RenderSettings(), settings(show_hud=hud, lights_total=1), frames=2)
        images[hud] = [encoded(v.image[..., :3]) for v in xr_runtime.captured()[-1].views]
    h = EYE[1]
    for plain, with_hud in zip(images[False], images[True], strict=True):
        changed = np.abs(plain - with_hud).max(axis=-1) > SRGB_TOLERANCE
        rows = np.nonzero(changed.any(axis=1))[0]  # row 0 at the bottom
        assert len(rows) > 0, "no HUD drawn"
        assert rows.max() < h // 2, "the HUD reached the top half"


@pytest.mark.opencl
def test_a_light_bake_is_played_back_and_named_in_the_status(xr_runtime, rng, gl_ctx, cl_context):
    """Issue 34: the bridge draws the scene's light bake through the one drawer: each eye
    equals an independent render of its pose with the bake (within sRGB 8-bit quantisation),
    which differs from the unbaked one; the status (and so the HUD and the CLI) names what
    plays back."""
    from dataclasses import replace

    from btf_addon.cl.bake import BakeKnobs, bake_scene
    from btf_addon.xr.bridge import run_bridge

    scene = small_scene(rng)
    scene.meshes = [
        replace(m, name=n) for m, n in zip(scene.meshes, ("Ball", "Floor"), strict=True)
    ]
    bake = bake_scene(scene, cl_context, BakeKnobs(spacing=0.5, view_bins=2, samples=16))
    baked = replace(scene, light_bake=bake)
    script(xr_runtime)
    # All 8 lights in the first frame, as the reference draws them: the GGX ball's unshadowed
    # light takes each batch's own directions (shaders/lobe_lib.glsl), so the same batches
    # give the same image
    status = run_bridge(
        baked,
        RenderSettings(use_antialiasing=False),  # the reference is drawn at pixel centres
        settings(converge=True, budget_s=10.0, lights_per_frame=8),
        frames=6,
    )
    assert status.bake == "Light bake: baked light on Ball, Floor"
    for view in xr_runtime.captured()[-1].views:
        ours = independent_render(gl_ctx, baked, view.pose, view.fov, 8)
        diff = np.abs(encoded(view.image[..., :3]) - encoded(ours))
        assert diff.max() <= SRGB_TOLERANCE, diff.max()
        live = independent_render(gl_ctx, scene, view.pose, view.fov, 8)
        assert np.abs(encoded(live) - encoded(ours)).max() > 20 * SRGB_TOLERANCE


@pytest.mark.parametrize(("scale", "size"), [(0.5, (24, 18)), (10.0, (192, 144))])
def test_resolution_scale_is_clamped_to_the_runtimes_maximum(xr_runtime, rng, scale, size):
    """The test runtime recommends 48×36 and allows 4× that (192×144)."""
    from btf_addon.xr.bridge import run_bridge

    script(xr_runtime)
    status = run_bridge(
        small_scene(rng), RenderSettings(), settings(resolution_scale=scale, lights_total=1), 1
    )
    assert status.eye_size == size
    assert xr_runtime.captured()[0].views[0].image.shape[:2] == (size[1], size[0])


def test_the_space_is_placed_at_the_camera_facing_its_heading():
    """A camera at (1, 2, 3) looking along +X, pitched down 30°: the head's first position
    lands on it, the space's forward (−z) on +X, its up (+y) on +Z; pitch is not used."""
    from btf_addon.xr.bridge import world_from_space

    pitch = math.radians(30)
    target = np.array([1.0 + math.cos(pitch), 2.0, 3.0 - math.sin(pitch)])
    m = world_from_space(look_at((1.0, 2.0, 3.0), target), np.array([0.1, 1.6, -0.2]))
    assert m @ [0.1, 1.6, -0.2, 1.0] == pytest.approx([1.0, 2.0, 3.0, 1.0])
    assert m[:3, :3] @ [0.0, 0.0, -1.0] == pytest.approx([1.0, 0.0, 0.0])
    assert m[:3, :3] @ [0.0, 1.0, 0.0] == pytest.approx([0.0, 0.0, 1.0])


def test_set_scene_keeps_the_unchanged_uploads(xr_runtime, rng):
    """A new scene with one material changed: the next frame's drawer re-uploads that BTF's
    tables only (meshes, the other BTF and the World kept), and both eyes start over."""
    from dataclasses import replace

    from btf_addon.xr.bridge import XRBridge

    script(xr_runtime)
    scene = small_scene(rng)
    bridge = XRBridge(scene, RenderSettings(), settings(lights_total=64))
    bridge.start()
    try:
        while bridge.frames < 3:
            assert bridge.run_frame()
        before = dict(bridge.status.lights_done)
        edited = replace(
            scene, materials=[Material(GGXBTF((0.2, 0.5, 0.9), 0.2)), *scene.materials[1:]]
        )
        bridge.set_scene(edited)
        frames = bridge.frames
        while bridge.frames == frames:
            assert bridge.run_frame()
        assert bridge.drawer.scene is edited
        assert bridge.drawer.uploads == {"tables": 1, "meshes": 0}
        # Started over: each eye holds just this frame's batch (it had more before).
        status = bridge.status
        assert status.lights_done == status.lights_per_frame, (before, status)
        assert all(before[eye] > 1 for eye in ("left", "right"))
    finally:
        bridge.close()


def test_a_stop_check_ends_the_run_and_closes_the_session(xr_runtime, rng, monkeypatch):
    """Issue 30 item 2: a Ctrl-C swallowed inside a frame (a ctypes callback, the driver) was
    lost and the run went on to its last frame. run_bridge asks its ``stop_check`` after every
    frame: the CLI passes cli/main.py ``raise_if_interrupted``, which re-raises a recorded
    signal; the bridge closes the session on the way out."""
    import signal

    from btf_addon.cli import main as cli_main
    from btf_addon.xr import bridge as bridge_module

    script(xr_runtime)
    closed, frames_seen = [], []
    real_close = bridge_module.XRBridge.close

    def close(self):
        closed.append(self.frames)
        return real_close(self)

    def stop_check():
        frames_seen.append(1)
        if len(frames_seen) == 3:  # the signal arrived during frame 3 and was swallowed there
            cli_main.signals_received.append(signal.SIGINT)
        cli_main.raise_if_interrupted()

    monkeypatch.setattr(bridge_module.XRBridge, "close", close)
    monkeypatch.setattr(cli_main, "signals_received", [])
    with pytest.raises(KeyboardInterrupt):
        bridge_module.run_bridge(
            small_scene(rng), RenderSettings(), settings(), frames=50, stop_check=stop_check
        )
    assert len(frames_seen) == 3 and closed and closed[0] <= 3

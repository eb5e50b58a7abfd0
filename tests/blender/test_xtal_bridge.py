"""The XTAL Bridge operator's controller (blender/vr/xtal_bridge.py) in background Blender.

Its wiring — export, the bridge's own thread, re-export when the depsgraph reports a change,
controller actions applied as undoable edits, failures surfaced, a clean stop — is driven here
with a bridge that stands in for ``xr.bridge.XRBridge`` at its Python interface (the thread
calls; no OpenXR). The real bridge against the OpenXR test runtime is tests/xr."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

import pytest
from blender_helpers import draw_panel, extension_submodule, sphere_on_ground


class StandInBridge:
    """``XRBridge``'s interface: start/run_frame/close on the bridge thread; set_scene,
    request_stop, status, pop_edits from Blender's. ``fail_start``: start raises that."""

    def __init__(self, scene, render_settings, settings, fail_start=None, edits=()):
        self.scenes = [scene]
        self.render_settings, self.settings = render_settings, settings
        self.fail_start = fail_start
        self.edits = list(edits)
        self.frames = 0
        self.stop = threading.Event()
        self.closed = False
        self.thread_names: set[str] = set()
        self.status = SimpleNamespace(
            runtime="stand-in",
            state="FOCUSED",
            fps=90.0,
            lights_per_frame={"left": 5},
            lights_done={},
            eye_size=(64, 48),
            values_from="runtime",
            message="",
        )

    def start(self):
        self.thread_names.add(threading.current_thread().name)
        if self.fail_start is not None:
            raise self.fail_start

    def run_frame(self):
        self.thread_names.add(threading.current_thread().name)
        self.frames += 1
        time.sleep(0.002)
        return not self.stop.is_set()

    def set_scene(self, scene):
        self.scenes.append(scene)

    def request_stop(self):
        self.stop.set()

    def close(self):
        self.thread_names.add(threading.current_thread().name)
        self.closed = True

    def pop_edits(self):
        edits, self.edits = self.edits, []
        return edits


@pytest.fixture
def bridge_scene(bpy_module, fresh_scene, tmp_path):
    from btf_addon.core.codecs.analytic import GGXBTF
    from btf_addon.core.formats.container import write_container

    write_container(tmp_path / "ggx.btfm", GGXBTF((0.9, 0.6, 0.3), 0.4))
    return sphere_on_ground(bpy_module, tmp_path, tmp_path / "ggx.btfm", segments=16, rings=8)


def controller_with(bpy, scene, **stand_in):
    module = extension_submodule("btf_addon.blender.vr.xtal_bridge")
    made = []

    def make(exported, render_settings, settings):
        made.append(StandInBridge(exported, render_settings, settings, **stand_in))
        return made[-1]

    return module.BridgeController(scene, bpy.context.view_layer, make_bridge=make), made


def test_the_bridge_runs_on_its_own_thread_and_gets_the_scenes_settings(bpy_module, bridge_scene):
    bpy = bpy_module
    bridge_scene.btf_bridge.lights_total, bridge_scene.btf_bridge.frame_budget_ms = 64, 0.0
    bridge_scene.btf_bridge.resolution_scale = 0.5
    controller, made = controller_with(bpy, bridge_scene)
    controller.start()
    try:
        assert controller.tick()
        (bridge,) = made
        assert bridge.settings.lights_total == 64 and bridge.settings.budget_s is None
        assert bridge.settings.resolution_scale == 0.5
        assert bridge.render_settings.lights_total == bridge_scene.btf_render.lights_total
        assert len(bridge.scenes[0].materials) == 2  # the BTF sphere and the plain ground
        assert "stand-in" in controller.status_text() and "90 FPS" in controller.status_text()
    finally:
        controller.stop()
    assert not controller.thread.is_alive() and bridge.closed
    assert bridge.thread_names == {"btf-xtal-bridge"}  # never Blender's thread
    assert controller._on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post


def test_a_change_in_blender_reaches_the_running_bridge(bpy_module, bridge_scene):
    bpy = bpy_module
    controller, made = controller_with(bpy, bridge_scene)
    controller.start()
    try:
        controller.tick()
        assert len(made[0].scenes) == 1
        bpy.data.objects["Sphere"].location.x += 0.5
        bpy.context.view_layer.update()  # runs depsgraph_update_post, as the UI would
        controller.tick()
        assert len(made[0].scenes) == 2
        moved = made[0].scenes[-1].meshes[0].world_from_object[0, 3]
        assert moved == pytest.approx(0.5)
    finally:
        controller.stop()


def test_controller_actions_become_undoable_scene_edits(bpy_module, bridge_scene):
    """An exposure press from the headset's controller changes the active object's BTF
    exposure, as the Wiimote's and Blender's VR session's do."""
    bpy = bpy_module
    actions = extension_submodule("btf_addon.controllers.actions")
    bpy.context.view_layer.objects.active = bpy.data.objects["Sphere"]
    press = actions.Edit(0.0, actions.Action.EXPOSURE_UP, 1.0 / 3.0)
    controller, _ = controller_with(bpy, bridge_scene, edits=[press])
    controller.start()
    try:
        controller.tick()
    finally:
        controller.stop()
    assert bpy.data.materials["BTF"].btf.exposure == pytest.approx(1.0 / 3.0)


def test_a_failure_to_start_is_reported_with_its_message(bpy_module, bridge_scene):
    bpy = bpy_module
    error = RuntimeError("no OpenXR runtime: install SteamVR or Monado")
    controller, _ = controller_with(bpy, bridge_scene, fail_start=error)
    controller.start()
    controller.thread.join(5.0)
    assert controller.tick() is False
    assert controller.error is error
    assert controller._on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post


def test_the_operator_and_panel_register_without_blenders_own_openxr(bpy_module, installed):
    bpy = bpy_module
    assert hasattr(bpy.types, "BTF_OT_xtal_bridge") and hasattr(bpy.types.Scene, "btf_bridge")
    xr = extension_submodule("btf_addon.blender.vr.preview")
    xr.unregister()
    try:
        xr.register(xr_available=False)
        assert hasattr(bpy.types, "BTF_OT_xtal_bridge")  # a separate module: always there
    finally:
        xr.unregister()
        xr.register()


def test_the_operator_drives_a_real_openxr_runtime(bpy_module, bridge_scene, tmp_path, monkeypatch):
    """The controller with the real bridge (the extension's bundled pyopenxr and its OpenXR
    loader) against the OpenXR test runtime (tests/xr_runtime, a simulated two-view HMD): the
    session runs on the bridge's thread while Blender's stays free, three frames of two eyes
    are submitted with our pixels in them, and it ends cleanly."""
    import json

    from xr_runtime.build import build_runtime, missing_tools
    from xr_runtime.readback import read_capture

    if missing_tools():
        pytest.skip("no OpenXR test runtime: missing " + "; ".join(missing_tools()))
    bpy = bpy_module
    manifest = build_runtime(tmp_path / "runtime")
    script = tmp_path / "script.json"
    capture = tmp_path / "capture"
    script.write_text(json.dumps({"eye_size": [48, 36], "capture_dir": str(capture)}))
    monkeypatch.setenv("XR_RUNTIME_JSON", str(manifest))
    monkeypatch.setenv("BTF_XR_TEST_SCRIPT", str(script))
    bridge_scene.btf_bridge.lights_total = 8
    module = extension_submodule("btf_addon.blender.vr.xtal_bridge")
    controller = module.BridgeController(bridge_scene, bpy.context.view_layer)
    controller.start(frames=3)
    try:
        controller.thread.join(60.0)
        assert controller.tick() is False
        assert controller.error is None, controller.error
        assert "BTF test runtime" in controller.status_text()
        # The panel while it runs: its status, and the light bake's line (none baked here).
        operator_class = module.BTF_OT_xtal_bridge
        operator_class._running = controller
        try:
            labels = draw_panel(module.VIEW3D_PT_btf_xtal_bridge, bpy.context).labels
        finally:
            operator_class._running = None
        assert any("BTF test runtime" in label for label in labels), labels
        assert controller.bake_text() == ""
    finally:
        controller.stop()
    frames = read_capture(capture)
    assert len(frames) == 3 and all(len(f.views) == 2 for f in frames)
    for view in frames[-1].views:
        assert view.image.shape == (36, 48, 4)
        assert view.image[..., :3].max() > 0.05  # the World and the sphere, not a cleared image

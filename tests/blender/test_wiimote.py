"""The Wiimote operator's logic in background Blender, driven by hand-written report streams
through the replay transport (timers never fire in background mode, so the operator's
``execute`` and the session it wraps run the recording synchronously)."""

from __future__ import annotations

import math

import pytest
from blender_helpers import extension_submodule, with_nodes
from helpers import studiolights_dir
from wiimote_streams import (
    ACK_WRITE,
    CALIBRATION_REPLY,
    NUNCHUK_CAL_REPLY,
    NUNCHUK_ID_REPLY,
    STATUS_EXTENSION,
    STATUS_NO_EXTENSION,
    records,
    report_0x37,
)

from btf_addon.controllers.replay import dump

# Status, the four IR writes' acks, the calibration reply, a first data report.
START = [
    (0.0, STATUS_NO_EXTENSION),
    *[(0.001 * (i + 1), ACK_WRITE) for i in range(4)],
    (0.01, CALIBRATION_REPLY),
    (0.02, report_0x37()),
]
# Buttons (big-endian): Right 0x0200, Up 0x0800, Plus 0x1000, B 0x0004, One 0x0002.
RIGHT, UP, PLUS, B_RIGHT, ONE, NONE = "0200", "0800", "1000", "0204", "0002", "0000"


def press(t: float, buttons: str) -> list[tuple[float, str]]:
    """Pressed at t, released 0.1 s later."""
    return [(t, report_0x37(buttons=buttons)), (t + 0.1, report_0x37(buttons=NONE))]


def hold(t0: float, t1: float, buttons: str) -> list[tuple[float, str]]:
    """Held from t0 to t1 (reports every 10 ms, the Wiimote's continuous rate), released at t1."""
    steps = round((t1 - t0) / 0.01)
    held = [(t0 + 0.01 * i, report_0x37(buttons=buttons)) for i in range(steps)]
    return [*held, (t1, report_0x37(buttons=NONE))]


def scene_for_wiimote(bpy):
    """A cube with two BTF materials in the file, a camera, an environment World."""
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("Cube")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    cube = bpy.data.objects.new("Cube", mesh)
    scene.collection.objects.link(cube)
    materials = []
    for name in ("BTF A", "BTF B"):
        mat = with_nodes(bpy.data.materials.new(name))
        mat.btf.enabled = True
        mat.btf.source = f"//{name}.btfm"
        materials.append(mat)
    mesh.materials.append(materials[0])
    bpy.context.view_layer.objects.active = cube
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, -5.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    world = with_nodes(bpy.data.worlds.new("W"))
    nodes, links = world.node_tree.nodes, world.node_tree.links
    texture = nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(str(studiolights_dir() / "forest.exr"))
    mapping = nodes.new("ShaderNodeMapping")
    links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
    links.new(texture.outputs["Color"], nodes["Background"].inputs["Color"])
    scene.world = world
    bpy.context.view_layer.update()  # matrix_world from the locations set above
    return cube, materials, mapping


def run_session(bpy, stream):
    session_mod = extension_submodule("btf_addon.blender.wiimote.session")
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    replay = extension_submodule("btf_addon.controllers.replay")
    ctx = edits.EditContext(bpy.context.scene, bpy.context.view_layer)
    session = session_mod.WiimoteSession(replay.ReplayTransport(stream), ctx)
    session.start()
    why = session.run_to_end()
    return session, why


def test_replay_performs_the_expected_edits(bpy_module, fresh_scene):
    bpy = bpy_module
    cube, (mat_a, mat_b), mapping = scene_for_wiimote(bpy)
    settings = bpy.context.scene.btf_render
    lights, progressive = settings.lights_per_redraw, settings.progressive
    stream = records(
        *START,
        *press(0.5, RIGHT),  # next material: B
        *press(1.0, PLUS),  # exposure +1/3 stop on B
        *hold(2.0, 4.0, B_RIGHT),  # environment +45°/s for 2 s = 90°
        *press(5.0, ONE),  # progressive off
        *press(5.5, UP),  # lights per redraw + 1
        (6.0, report_0x37()),
    )
    session, why = run_session(bpy, stream)
    assert why == "the recording ended"
    assert not [m for m in session.messages if "ack" in m or "no reply" in m]
    assert cube.material_slots[0].material == mat_b
    assert mat_b.btf.exposure == pytest.approx(1 / 3) and mat_a.btf.exposure == 0.0
    # 200 reports 10 ms apart: the hold lasts exactly 2 s of report time. Float32 storage.
    assert mapping.inputs["Rotation"].default_value[2] == pytest.approx(math.pi / 2, abs=1e-6)
    assert settings.progressive is (not progressive)
    assert settings.lights_per_redraw == lights + 1
    assert session.undo_steps == [
        "Wiimote: Next material",
        "Wiimote: Exposure +",
        "Wiimote: Rotate environment",  # one step for the whole 2 s gesture
        "Wiimote: Progressive on/off",
        "Wiimote: Lights per frame +",
    ]
    # Rumble on the mode change: the LED report with bit 0 set, then without.
    written = [r.data.hex() for r in session.transport.written]
    assert "1111" in written and written[-1] == "1110"


def test_abrupt_end_mid_gesture_leaves_the_scene_intact(bpy_module, fresh_scene):
    bpy = bpy_module
    cube, (mat_a, _), mapping = scene_for_wiimote(bpy)
    before = (len(bpy.data.objects), len(bpy.data.materials), len(bpy.data.worlds))
    held = [(1.0 + 0.01 * i, report_0x37(buttons=B_RIGHT)) for i in range(51)]  # 1.0 .. 1.5
    session, why = run_session(bpy, records(*START, *held, (1.505, "37 0204 80")))  # truncated
    assert why == "the recording ended"
    # Held from 1.0 s to the last report (1.505 s, truncated: its time still counts, its
    # bytes do not): 0.505 s × 45°/s, and nothing after the stream ended.
    assert mapping.inputs["Rotation"].default_value[2] == pytest.approx(
        math.radians(45.0 * 0.505), abs=1e-6
    )
    assert session.undo_steps == ["Wiimote: Rotate environment"]  # the gesture was closed
    assert (len(bpy.data.objects), len(bpy.data.materials), len(bpy.data.worlds)) == before
    assert cube.material_slots[0].material == mat_a
    assert bpy.context.scene.world.node_tree.nodes["Mapping"] == mapping
    assert any(e.kind == "truncated" for e in session.wiimote.events)


def test_operator_plays_a_recording_file(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    cube, (_, mat_b), mapping = scene_for_wiimote(bpy)
    path = tmp_path / "session.jsonl"
    dump(records(*START, *press(0.5, RIGHT), *hold(1.0, 2.0, B_RIGHT)), path)
    assert bpy.ops.btf.wiimote_control(replay_path=str(path)) == {"FINISHED"}
    assert cube.material_slots[0].material == mat_b
    assert mapping.inputs["Rotation"].default_value[2] == pytest.approx(
        math.radians(45.0), abs=1e-6
    )
    with pytest.raises(RuntimeError, match="recording not found"):
        bpy.ops.btf.wiimote_control(replay_path=str(tmp_path / "missing.jsonl"))


def test_edited_binding_rate_from_preferences(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    _, _, mapping = scene_for_wiimote(bpy)
    prefs = extension_submodule("btf_addon.blender.wiimote.preferences")
    wiimote_prefs = prefs.wiimote_preferences()
    assert wiimote_prefs is not None
    assert bpy.ops.btf.wiimote_reset_bindings() == {"FINISHED"}
    defaults = extension_submodule("btf_addon.controllers.bindings").default_bindings()

    def same(stored, expected) -> bool:  # Blender stores the numbers as float32 (rel 6e-8)
        def split(b):
            return (b.action, b.input, b.kind, b.modifiers, b.axis), (
                b.rate,
                b.dead_zone,
                b.full_scale,
            )

        return len(stored) == len(expected) and all(
            split(a)[0] == split(b)[0] and split(a)[1] == pytest.approx(split(b)[1], rel=1e-6)
            for a, b in zip(stored, expected, strict=True)
        )

    assert same(prefs.current_bindings(), defaults)
    for item in wiimote_prefs.bindings:
        if item.action == "ROTATE_ENVIRONMENT" and item.input == "RIGHT":
            item.rate = 90.0
    path = tmp_path / "s.jsonl"
    dump(records(*START, *hold(1.0, 2.0, B_RIGHT)), path)
    try:
        assert bpy.ops.btf.wiimote_control(replay_path=str(path)) == {"FINISHED"}
        assert mapping.inputs["Rotation"].default_value[2] == pytest.approx(
            math.radians(90.0), abs=1e-6
        )
    finally:
        wiimote_prefs.bindings.clear()  # back to the defaults for other tests
    assert prefs.current_bindings() == defaults  # an empty list: the defaults themselves


def test_view_and_object_edits(bpy_module, fresh_scene):
    bpy = bpy_module
    cube, _, _ = scene_for_wiimote(bpy)
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    actions = extension_submodule("btf_addon.controllers.actions")
    Action, Edit = actions.Action, actions.Edit  # noqa: N806 - the extension's classes
    ctx = edits.EditContext(bpy.context.scene, bpy.context.view_layer)
    ctx.save_view()
    camera = bpy.context.scene.camera
    edits.apply_edit(ctx, Edit(0.0, Action.ORBIT_CAMERA, 90.0, "YAW"))
    # Camera at (0, -5, 0) orbits 90° about the cube's origin: stick right moves it right.
    assert tuple(camera.matrix_world.translation) == pytest.approx((5.0, 0.0, 0.0), abs=1e-5)
    edits.apply_edit(ctx, Edit(0.0, Action.ORBIT_CAMERA, 30.0, "PITCH"))  # stick up: lift
    assert camera.matrix_world.translation.z == pytest.approx(5.0 * math.sin(math.radians(30)))
    edits.apply_edit(ctx, Edit(0.0, Action.ZOOM_IN, 1.0))
    assert camera.matrix_world.translation.length == pytest.approx(2.5, abs=1e-5)
    edits.apply_edit(ctx, Edit(0.0, Action.RESET_VIEW))
    assert tuple(camera.matrix_world.translation) == pytest.approx((0.0, -5.0, 0.0), abs=1e-6)
    edits.apply_edit(ctx, Edit(0.0, Action.ROTATE_OBJECT, 30.0, "Z"))
    assert cube.matrix_world.to_euler().z == pytest.approx(math.radians(30.0), abs=1e-6)
    with pytest.raises(edits.EditSkipped, match=r"background"):
        edits.apply_edit(ctx, Edit(0.0, Action.SCREENSHOT))
    # Next object: the view layer's meshes by name, wrapping around; cameras are skipped.
    other = bpy.data.objects.new("Another", bpy.data.meshes.new("Another"))
    bpy.context.scene.collection.objects.link(other)
    bpy.context.view_layer.update()  # the view layer lists objects linked since its last sync
    assert edits.apply_edit(ctx, Edit(0.0, Action.NEXT_OBJECT)) == "object Another"
    assert bpy.context.view_layer.objects.active == other and other.select_get()
    assert edits.apply_edit(ctx, Edit(0.0, Action.NEXT_OBJECT)) == "object Cube"
    # Lights per redraw stays within the property's range.
    settings = bpy.context.scene.btf_render
    settings.lights_per_redraw = 2
    for _ in range(3):
        edits.apply_edit(ctx, Edit(0.0, Action.LIGHTS_FEWER))
    assert settings.lights_per_redraw == 1


def test_nunchuk_plugged_mid_session_orbits_the_camera(bpy_module, fresh_scene):
    bpy = bpy_module
    scene_for_wiimote(bpy)
    camera = bpy.context.scene.camera
    stick_right = "e0 80 80 80 b3 03"  # stick x at its calibrated maximum, C and Z released
    stream = records(
        *START,
        (0.5, STATUS_EXTENSION),
        (0.51, ACK_WRITE),
        (0.52, ACK_WRITE),
        (0.53, NUNCHUK_ID_REPLY),
        (0.54, NUNCHUK_CAL_REPLY),
        *[(1.0 + 0.01 * i, report_0x37(ext=stick_right)) for i in range(150)],  # 1.0 .. 2.49
        (2.5, report_0x37(ext="80 80 80 80 b3 03")),  # centred
    )
    session, _ = run_session(bpy, stream)
    assert session.wiimote.extension == "nunchuk"
    # 60°/s for 1.5 s = 90° about the cube at the origin: (0, −5, 0) → (5, 0, 0).
    assert tuple(camera.matrix_world.translation) == pytest.approx((5.0, 0.0, 0.0), abs=1e-4)
    assert session.undo_steps == ["Wiimote: Orbit camera"]


def test_undo_steps_are_real(bpy_module, fresh_scene):
    bpy = bpy_module
    scene_for_wiimote(bpy)
    bpy.ops.ed.undo_push(message="scene set up")
    session, _ = run_session(bpy, records(*START, *press(0.5, RIGHT), *press(1.0, PLUS)))
    assert bpy.data.materials["BTF B"].btf.exposure == pytest.approx(1 / 3)
    bpy.ops.ed.undo()  # one step: the exposure change (undo reloads: look everything up again)
    assert bpy.data.materials["BTF B"].btf.exposure == 0.0
    assert bpy.data.objects["Cube"].material_slots[0].material.name == "BTF B"
    bpy.ops.ed.undo()  # the next: the material change
    assert bpy.data.objects["Cube"].material_slots[0].material.name == "BTF A"
    # A session that outlives an undo still edits the scene (it holds names, not references).
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    actions = extension_submodule("btf_addon.controllers.actions")
    edits.apply_edit(session.ctx, actions.Edit(2.0, actions.Action.NEXT_MATERIAL))
    assert bpy.data.objects["Cube"].material_slots[0].material.name == "BTF B"


def test_help_overlay_draws_the_bindings(bpy_module, fresh_scene):
    """The overlay's draw callback, run into an offscreen with a pixel-space projection (what
    a POST_PIXEL handler gets): the backdrop and the text are drawn only while help is on."""
    import gpu
    import numpy as np
    from blender_helpers import init_gpu_module
    from mathutils import Matrix

    bpy = bpy_module
    init_gpu_module(bpy)
    overlay = extension_submodule("btf_addon.blender.wiimote.overlay")
    bindings = extension_submodule("btf_addon.controllers.bindings").default_bindings()
    width, height = 520, 560
    offscreen = gpu.types.GPUOffScreen(width, height)

    def draw(visible: bool) -> np.ndarray:
        overlay._source = lambda: (visible, bindings)
        with offscreen.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0))
            pixel_space = Matrix.Translation((-1.0, -1.0, 0.0)) @ Matrix.Diagonal(
                (2.0 / width, 2.0 / height, 1.0, 1.0)
            )
            with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
                gpu.matrix.load_identity()
                gpu.matrix.load_projection_matrix(pixel_space)
                overlay._draw()
            buffer = fb.read_color(0, 0, width, height, 4, 0, "FLOAT")
        buffer.dimensions = width * height * 4
        return np.array(buffer, dtype=np.float32).reshape(height, width, 4)

    try:
        hidden = draw(False)
        shown = draw(True)
    finally:
        overlay._source = None
        offscreen.free()
    assert not hidden.any()
    # Inside the backdrop quad (from (20, 40)), left of the text: black at the overlay's 0.6
    # alpha over a transparent target; 1/255 for an 8-bit target's rounding.
    np.testing.assert_allclose(shown[45, 25], (0.0, 0.0, 0.0, 0.6), atol=1 / 255)
    assert not shown[10, 10].any()  # outside the quad: untouched
    # Text: bright pixels (white or amber) on the backdrop, several rows of them.
    bright = shown[..., :3].max(axis=2) > 0.3
    rows_with_text = np.flatnonzero(bright.any(axis=1))
    assert len(rows_with_text) > 100  # 20 lines of 14 px text


def test_environment_without_mapping_gets_one_and_exposure_without_active_object(
    bpy_module, fresh_scene
):
    bpy = bpy_module
    _, (mat_a, _), mapping = scene_for_wiimote(bpy)
    tree = bpy.context.scene.world.node_tree
    tree.nodes.remove(mapping)  # the Environment Texture's Vector is now unlinked
    bpy.context.view_layer.objects.active = None
    run_session(bpy, records(*START, *hold(1.0, 2.0, B_RIGHT), *press(3.0, PLUS)))
    inserted = [n for n in tree.nodes if n.bl_idname == "ShaderNodeMapping"]
    assert len(inserted) == 1
    assert inserted[0].inputs["Rotation"].default_value[2] == pytest.approx(
        math.radians(45.0), abs=1e-6
    )
    env = extension_submodule("btf_addon.blender.export.world").environment_from_world(
        bpy.context.scene.world
    )
    assert env.messages == [] and env.environment.rotation_z_rad == pytest.approx(
        math.radians(45.0), abs=1e-6
    )
    assert mat_a.btf.exposure == pytest.approx(1 / 3)  # the BTF material in view


def two_cubes(bpy):
    """The Wiimote scene's two BTF materials and two cubes at x = −2 and +2, both wearing the
    first material."""
    _, (mat_a, mat_b), _ = scene_for_wiimote(bpy)
    cubes = []
    for x in (-2.0, 2.0):
        bpy.ops.mesh.primitive_cube_add(size=1.0, location=(x, 0.0, 0.0))
        cube = bpy.context.view_layer.objects.active
        cube.data.materials.append(mat_a)
        cubes.append(cube)
    return (mat_a, mat_b), tuple(cubes)


def test_ir_pointer_picks_the_object_a_material_change_acts_on(bpy_module, fresh_scene):
    bpy = bpy_module
    (mat_a, mat_b), (left, right) = two_cubes(bpy)
    camera = bpy.context.scene.camera
    camera.location = (0.0, -10.0, 0.0)
    camera.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looking along +Y
    bpy.context.view_layer.objects.active = left
    bpy.context.view_layer.update()
    # Two dots at x 100 and 300, y 383 (basic IR bytes, hi byte 0x45): midpoint x 200 →
    # pointer x = 1 − 400/1023 ≈ 0.61, on the right cube (it spans about 0.42..0.69 of the
    # 50 mm camera's half width at 10 m); y ≈ 0.
    pointing = "647f452c7f" + "ff" * 5
    stream = records(
        *START, (0.5, report_0x37(ir=pointing)), (0.6, report_0x37(RIGHT, ir=pointing))
    )
    run_session(bpy, stream)
    assert right.material_slots[0].material == mat_b
    assert left.material_slots[0].material == mat_a  # the active object was not touched


def test_bindings_are_saved_and_restored_with_the_preferences(bpy_module, installed):
    """Edited bindings go into userpref.blend (the session's isolated user folder) and come
    back in a new Blender process that reads the preferences."""
    import os
    import subprocess
    import sys

    if not extension_submodule("btf_addon.blender.compat").at_least(4, 5):
        # Checked: `import bpy; bpy.ops.wm.read_userpref()` alone segfaults with the bpy 4.2.23
        # module (no add-on involved), so the second process cannot read the file back there.
        pytest.skip("bpy 4.2 as a Python module crashes in wm.read_userpref")
    bpy = bpy_module
    wiimote_prefs = extension_submodule("btf_addon.blender.wiimote.preferences")
    prefs = wiimote_prefs.wiimote_preferences()
    assert bpy.ops.btf.wiimote_reset_bindings() == {"FINISHED"}
    prefs.bindings[8].rate = 77.0  # B + Right: environment °/s
    prefs.ir_sensitivity = 5
    try:
        assert bpy.ops.wm.save_userpref() == {"FINISHED"}
        code = (
            "import bpy\n"
            "bpy.ops.wm.read_userpref()\n"
            "from bl_ext.user_default.btf_materials.btf_addon.blender.wiimote import preferences"
            " as wp\n"
            "p = wp.wiimote_preferences()\n"
            "b = wp.current_bindings()[8]\n"
            "print('RESTORED', len(p.bindings), b.action.name, b.input, b.rate, p.ir_sensitivity)\n"
            "from bl_ext.user_default.btf_materials.btf_addon.blender import compat\n"
            "compat.exit_python(0)\n"
        )
        proc = subprocess.run(
            [sys.executable, "-c", code], env=dict(os.environ), capture_output=True, text=True
        )
        assert "RESTORED 19 ROTATE_ENVIRONMENT RIGHT 77.0 5" in proc.stdout, proc.stderr[-2000:]
    finally:
        prefs.bindings.clear()
        prefs.ir_sensitivity = 3
        bpy.ops.wm.save_userpref()


# ------------------------------------------------- the operator's life cycle, without a window
# Background Blender runs ``execute`` only and fires no timers: the interactive path (invoke,
# modal, cancel) is driven here with a stand-in operator that borrows the real methods, a
# window manager that passes timers through to Blender's and records modal handlers, and a
# screen of stand-in 3D view areas.


class FakeArea:
    type = "VIEW_3D"

    def __init__(self) -> None:
        from mathutils import Quaternion, Vector

        self.redraws = 0
        self.region_3d = type("R3D", (), {})()
        self.region_3d.view_location = Vector()
        self.region_3d.view_rotation = Quaternion()
        self.region_3d.view_distance = 10.0
        self.regions = [type("Region", (), {"type": "WINDOW", "width": 800, "height": 600})()]
        self.spaces = type("Spaces", (), {"active": type("Space", (), {})()})()
        self.spaces.active.region_3d = self.region_3d

    def tag_redraw(self) -> None:
        self.redraws += 1

    def as_pointer(self) -> int:
        return id(self)


class FakeWindowManager:
    def __init__(self, wm) -> None:
        self.wm, self.live, self.handlers = wm, [], []

    def event_timer_add(self, step, window=None):
        timer = self.wm.event_timer_add(step, window=window)
        self.live.append(timer)
        return timer

    def event_timer_remove(self, timer) -> None:
        self.wm.event_timer_remove(timer)
        self.live = [t for t in self.live if t != timer]

    def modal_handler_add(self, operator) -> bool:
        self.handlers.append(operator)
        return True


class FakeContext:
    def __init__(self, bpy, areas) -> None:
        self.scene, self.view_layer = bpy.context.scene, bpy.context.view_layer
        self.window_manager = FakeWindowManager(bpy.context.window_manager)
        self.screen = type("Screen", (), {"areas": areas})()
        self.area = self.window = None


class Event:
    def __init__(self, type_: str) -> None:
        self.type = type_


def fake_operator(op_mod, replay_path: str = "", realtime: bool = True):
    cls = op_mod.BTF_OT_wiimote_control
    names = ("execute", "invoke", "modal", "cancel", "_session", "_finish", "_cleanup")
    methods = {name: cls.__dict__[name] for name in (*names, "_report_end") if name in cls.__dict__}

    def report(self, kind, text) -> None:
        self.reports.append((next(iter(kind)), text))

    operator = type("FakeOperator", (), {**methods, "report": report})()
    operator.replay_path, operator.realtime, operator.reports = replay_path, realtime, []
    return operator


def _end_any_session(op_mod) -> None:
    session = op_mod._running.get("session")
    op_mod._running.clear()
    if session is not None:
        session.stop()
    extension_submodule("btf_addon.blender.wiimote.overlay").hide()


@pytest.fixture
def wiimote_operator(bpy_module, fresh_scene):
    """The operator module, with no live session before and after the test."""
    op_mod = extension_submodule("btf_addon.blender.wiimote.operator")
    _end_any_session(op_mod)
    yield op_mod
    _end_any_session(op_mod)


@pytest.fixture
def opened(wiimote_operator, monkeypatch):
    """Every transport the operator opens, and every session it makes."""
    session_mod = extension_submodule("btf_addon.blender.wiimote.session")
    found = {"transports": [], "sessions": []}

    class Replay(wiimote_operator.ReplayTransport):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            found["transports"].append(self)

    class Session(session_mod.WiimoteSession):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            found["sessions"].append(self)

    monkeypatch.setattr(wiimote_operator, "ReplayTransport", Replay)
    monkeypatch.setattr(wiimote_operator, "WiimoteSession", Session)
    return found


def closed(transport) -> bool:
    return transport._closed


def test_replay_execute_releases_the_recording(bpy_module, opened, wiimote_operator, tmp_path):
    bpy = bpy_module
    scene_for_wiimote(bpy)
    path = tmp_path / "session.jsonl"
    dump(records(*START, *press(0.5, RIGHT)), path)
    assert bpy.ops.btf.wiimote_control(replay_path=str(path)) == {"FINISHED"}
    (transport,) = opened["transports"]
    assert closed(transport) and opened["sessions"][0].closed
    assert wiimote_operator._running == {}  # nothing keeps the ended session alive


def test_a_failing_start_closes_the_transport(
    bpy_module, opened, wiimote_operator, tmp_path, monkeypatch
):
    bpy = bpy_module
    scene_for_wiimote(bpy)
    path = tmp_path / "session.jsonl"
    dump(records(*START), path)
    errors = extension_submodule("btf_addon.controllers.transport")

    def start(self) -> None:
        raise errors.ControllerError("the Wiimote did not answer")

    monkeypatch.setattr(wiimote_operator.WiimoteSession, "start", start)
    with pytest.raises(RuntimeError, match="did not answer"):
        bpy.ops.btf.wiimote_control(replay_path=str(path))
    (transport,) = opened["transports"]
    assert closed(transport)


def test_a_binding_whose_kind_does_not_fit_its_action_is_reported(
    bpy_module, opened, wiimote_operator, tmp_path
):
    bpy = bpy_module
    scene_for_wiimote(bpy)
    prefs = extension_submodule("btf_addon.blender.wiimote.preferences")
    errors = extension_submodule("btf_addon.controllers.transport")
    wiimote_prefs = prefs.wiimote_preferences()
    assert bpy.ops.btf.wiimote_reset_bindings() == {"FINISHED"}
    path = tmp_path / "s.jsonl"
    dump(records(*START, *press(0.5, RIGHT)), path)
    try:
        assert wiimote_prefs.bindings[1].action == "NEXT_MATERIAL"
        wiimote_prefs.bindings[1].kind = "HOLD"  # a toggle per poll while held
        message = r"Wiimote binding 2: a HOLD binding cannot drive NEXT_MATERIAL"
        with pytest.raises(errors.ControllerError, match=message):
            prefs.current_bindings()
        with pytest.raises(RuntimeError, match=message):
            bpy.ops.btf.wiimote_control(replay_path=str(path))
        assert opened["transports"] == []  # the bindings are read before anything is opened
        wiimote_prefs.bindings[1].kind = "PRESS"
        wiimote_prefs.bindings[16].kind = "PRESS"  # Zoom in on C: a gesture without an end
        assert wiimote_prefs.bindings[16].action == "ZOOM_IN"
        with pytest.raises(errors.ControllerError, match="PRESS binding cannot drive ZOOM_IN"):
            prefs.current_bindings()
    finally:
        wiimote_prefs.bindings.clear()


def test_modal_session_ends_on_disconnect_and_releases_the_device(
    bpy_module, opened, wiimote_operator, tmp_path
):
    bpy = bpy_module
    cube, (_, mat_b), _ = scene_for_wiimote(bpy)
    path = tmp_path / "s.jsonl"
    dump(records(*START, *press(0.5, RIGHT)), path)
    area = FakeArea()
    context = FakeContext(bpy, [area])
    operator = fake_operator(wiimote_operator, str(path), realtime=False)
    assert operator.invoke(context, Event("NONE")) == {"RUNNING_MODAL"}
    assert context.window_manager.handlers == [operator] and context.window_manager.live
    assert operator.modal(context, Event("MOUSEMOVE")) == {"PASS_THROUGH"}
    # One poll reads the whole recording, then its end: the Wiimote "went away".
    assert operator.modal(context, Event("TIMER")) == {"FINISHED"}
    assert cube.material_slots[0].material == mat_b
    (transport,) = opened["transports"]
    assert closed(transport)
    assert wiimote_operator._running == {} and context.window_manager.live == []
    assert wiimote_operator.last_message[0].startswith("Recording played to the end")
    assert area.redraws >= 1


def test_cancel_ends_the_session_and_a_new_one_can_start(
    bpy_module, opened, wiimote_operator, tmp_path
):
    """File > Open/New/Revert end a modal operator through ``cancel`` (no event)."""
    bpy = bpy_module
    scene_for_wiimote(bpy)
    overlay = extension_submodule("btf_addon.blender.wiimote.overlay")
    path = tmp_path / "s.jsonl"
    dump(records(*START, (60.0, report_0x37())), path)  # realtime: still running in a minute
    context = FakeContext(bpy, [FakeArea()])
    operator = fake_operator(wiimote_operator, str(path))
    assert operator.invoke(context, Event("NONE")) == {"RUNNING_MODAL"}
    assert "session" in wiimote_operator._running and overlay._source is not None
    operator.cancel(context)
    (transport,) = opened["transports"]
    assert closed(transport) and opened["sessions"][0].ended == "stopped"
    assert wiimote_operator._running == {} and context.window_manager.live == []
    assert overlay._source is None
    # The panel offers a new session, and one starts.
    again = fake_operator(wiimote_operator, str(path))
    assert again.invoke(context, Event("NONE")) == {"RUNNING_MODAL"}
    assert wiimote_operator._running["session"] is opened["sessions"][1]
    # Disabling the add-on ends it; the modal handler Blender still holds then cancels
    # itself on its next event instead of failing.
    wiimote_operator.unregister()
    try:
        assert closed(opened["transports"][1]) and wiimote_operator._running == {}
        assert again.modal(context, Event("TIMER")) == {"CANCELLED"}
        assert context.window_manager.live == [] and overlay._source is None
    finally:
        wiimote_operator.register()


def test_modal_polls_look_the_view_up_again_and_redraw_only_on_change(
    bpy_module, opened, wiimote_operator, tmp_path
):
    import time

    bpy = bpy_module
    scene_for_wiimote(bpy)
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    actions = extension_submodule("btf_addon.controllers.actions")
    path = tmp_path / "s.jsonl"
    dump(records(*START, (60.0, report_0x37())), path)
    area = FakeArea()
    context = FakeContext(bpy, [area])
    operator = fake_operator(wiimote_operator, str(path))
    assert operator.invoke(context, Event("NONE")) == {"RUNNING_MODAL"}
    session = wiimote_operator._running["session"]
    time.sleep(0.05)  # the start-up reports are due
    assert operator.modal(context, Event("TIMER")) == {"PASS_THROUGH"}
    redraws = area.redraws
    for _ in range(5):  # idle: nothing changed, nothing redrawn
        assert operator.modal(context, Event("TIMER")) == {"PASS_THROUGH"}
    assert area.redraws == redraws
    # The user closes the 3D view: the next poll finds none, and the view edits skip.
    context.screen.areas = []
    assert operator.modal(context, Event("TIMER")) == {"PASS_THROUGH"}
    assert session.ctx.region_3d is None and session.ctx.region is None
    camera = bpy.context.scene.camera.matrix_world.copy()
    for edit in (
        actions.Edit(1.0, actions.Action.ORBIT_CAMERA, 10.0, "YAW"),
        actions.Edit(1.0, actions.Action.ZOOM_IN, 1.0),
        actions.Edit(1.0, actions.Action.RESET_VIEW),
    ):
        with pytest.raises(edits.EditSkipped, match="3D view is gone"):
            edits.apply_edit(session.ctx, edit)
    assert bpy.context.scene.camera.matrix_world == camera  # not the camera instead
    # A 3D view again (another area): found on the next poll, and orbit turns it.
    other = FakeArea()
    context.screen.areas = [other]
    assert operator.modal(context, Event("TIMER")) == {"PASS_THROUGH"}
    assert session.ctx.region_3d is other.region_3d
    edits.apply_edit(session.ctx, actions.Edit(1.0, actions.Action.ORBIT_CAMERA, 10.0, "YAW"))
    assert other.region_3d.view_rotation != area.region_3d.view_rotation
    assert operator.modal(context, Event("ESC")) == {"FINISHED"}
    assert closed(opened["transports"][0]) and wiimote_operator._running == {}


def test_environment_rotation_skips_a_world_with_its_nodes_switched_off(
    bpy_module, fresh_scene, monkeypatch
):
    bpy = bpy_module
    _, _, mapping = scene_for_wiimote(bpy)
    world = bpy.context.scene.world
    world.node_tree.nodes.remove(mapping)  # unlinked: a rotation would insert nodes
    compat = extension_submodule("btf_addon.blender.compat")
    if compat.at_least(5, 0):  # 5.0 always uses the nodes: the switch as 4.2 to 4.5 have it
        monkeypatch.setattr(compat, "world_nodes_switched_off", lambda w: w == world)
    else:
        world.use_nodes = False
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    actions = extension_submodule("btf_addon.controllers.actions")
    ctx = edits.EditContext(bpy.context.scene, bpy.context.view_layer)
    before = len(world.node_tree.nodes)
    with pytest.raises(edits.EditSkipped, match="nodes are switched off"):
        edits.apply_edit(ctx, actions.Edit(0.0, actions.Action.ROTATE_ENVIRONMENT, 10.0))
    assert len(world.node_tree.nodes) == before


def test_lights_per_redraw_stays_within_the_property_limits(bpy_module, fresh_scene):
    bpy = bpy_module
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    actions = extension_submodule("btf_addon.controllers.actions")
    settings = bpy.context.scene.btf_render
    prop = settings.bl_rna.properties["lights_per_redraw"]
    assert edits.lights_range(settings) == (prop.hard_min, prop.hard_max)
    ctx = edits.EditContext(bpy.context.scene, bpy.context.view_layer)
    settings.lights_per_redraw = prop.hard_max - 1
    for _ in range(3):
        edits.apply_edit(ctx, actions.Edit(0.0, actions.Action.LIGHTS_MORE))
    assert settings.lights_per_redraw == prop.hard_max


def test_lights_per_frame_in_a_headset_changes_what_the_headset_reads(bpy_module, fresh_scene):
    """In Blender's VR session "Lights per frame +/-" steps the headset's own lights per frame
    (``scene.btf_vr``, which the VR draw callback reads; switched to a fixed count, since the
    frame budget would otherwise choose K), not the viewport's lights per redraw."""
    from mathutils import Vector

    bpy = bpy_module
    scene = bpy.context.scene
    if not hasattr(scene, "btf_vr"):
        pytest.skip("this Blender build has no OpenXR: no VR session, no scene.btf_vr")
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    actions = extension_submodule("btf_addon.controllers.actions")
    sync = extension_submodule("btf_addon.blender.sync")
    ctx = edits.EditContext(scene, bpy.context.view_layer)
    ctx.xr_source = lambda: _vr_state(Vector((0.0, -4.0, 1.0)))
    redraw, per_frame = scene.btf_render.lights_per_redraw, scene.btf_vr.lights_per_frame
    assert scene.btf_vr.lights_mode == "BUDGET"
    message = edits.apply_edit(ctx, actions.Edit(0.0, actions.Action.LIGHTS_MORE))
    read = sync.vr_settings(scene)  # what the headset's callback reads
    assert not read.use_budget and read.lights_per_frame == per_frame + 1
    assert scene.btf_render.lights_per_redraw == redraw  # the viewport's K is untouched
    assert message == f"VR lights per frame {per_frame + 1} (fixed)"
    for _ in range(100):  # the panel's range holds
        edits.apply_edit(ctx, actions.Edit(0.0, actions.Action.LIGHTS_MORE))
    assert scene.btf_vr.lights_per_frame == edits.lights_range(scene.btf_vr, "lights_per_frame")[1]
    ctx.xr_source = lambda: None  # the session ended: the viewport's K again
    edits.apply_edit(ctx, actions.Edit(0.0, actions.Action.LIGHTS_FEWER))
    assert scene.btf_render.lights_per_redraw == redraw - 1


# ------------------------------------------------- the VR half (issue 13), with a stand-in state
def _vr_state(viewer_location):
    """XrSessionState's attribute names, for a session Blender cannot start headless: the
    viewer at ``viewer_location`` looking along +Y (its −Z turned 90° about X)."""
    from types import SimpleNamespace

    from mathutils import Quaternion, Vector

    return SimpleNamespace(
        viewer_pose_location=viewer_location,
        viewer_pose_rotation=Quaternion((1.0, 0.0, 0.0), math.pi / 2),
        navigation_location=Vector(),
        navigation_rotation=Quaternion(),
        navigation_scale=1.0,
    )


def test_in_vr_targeted_edits_without_a_pointer_act_on_the_gazed_object(bpy_module, fresh_scene):
    bpy = bpy_module
    (mat_a, mat_b), (left, right) = two_cubes(bpy)
    bpy.context.view_layer.objects.active = left
    bpy.context.view_layer.update()
    session_mod = extension_submodule("btf_addon.blender.wiimote.session")
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    replay = extension_submodule("btf_addon.controllers.replay")

    def play(xr_state, stream):
        ctx = edits.EditContext(bpy.context.scene, bpy.context.view_layer)
        ctx.xr_source = lambda: xr_state
        session = session_mod.WiimoteSession(replay.ReplayTransport(stream), ctx)
        session.start()
        session.run_to_end()
        return session

    # The headset at (2, −10, 0) looks at the right cube; no IR dots, so no pointer.
    play(_vr_state((2.0, -10.0, 0.0)), records(*START, *press(0.5, RIGHT), *press(1.0, PLUS)))
    assert right.material_slots[0].material == mat_b
    assert mat_b.btf.exposure == pytest.approx(1 / 3)  # the gazed object's material
    assert left.material_slots[0].material == mat_a and mat_a.btf.exposure == 0.0
    # Looking between the cubes (nothing under the gaze): the active object, as on the desktop.
    play(_vr_state((0.0, -10.0, 0.0)), records(*START, *press(0.5, RIGHT)))
    assert left.material_slots[0].material == mat_b
    # Outside VR (no state): the active object again, and no gaze is asked for.
    play(None, records(*START, *press(0.5, RIGHT)))
    assert left.material_slots[0].material == mat_a


def test_in_vr_reset_view_resets_the_navigation_and_keeps_the_camera(bpy_module, fresh_scene):
    bpy = bpy_module
    scene_for_wiimote(bpy)
    from mathutils import Quaternion, Vector

    session_mod = extension_submodule("btf_addon.blender.wiimote.session")
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    replay = extension_submodule("btf_addon.controllers.replay")
    camera = bpy.context.scene.camera.matrix_world.copy()
    state = _vr_state((0.0, -5.0, 1.6))
    state.navigation_location = Vector((1.0, 2.0, 0.0))
    state.navigation_rotation = Quaternion((0.0, 0.0, 1.0), 1.0)
    state.navigation_scale = 2.0
    ctx = edits.EditContext(bpy.context.scene, bpy.context.view_layer)
    ctx.xr_source = lambda: state
    # Home + A: Home held, A pressed and released, then Home released (the one combo).
    home, home_a = "0080", "0088"
    stream = records(
        *START,
        (0.5, report_0x37(buttons=home)),
        (0.6, report_0x37(buttons=home_a)),
        (0.7, report_0x37(buttons=home)),
        (0.8, report_0x37(buttons=NONE)),
    )
    session = session_mod.WiimoteSession(replay.ReplayTransport(stream), ctx)
    session.start()
    session.run_to_end()
    assert "Wiimote: Reset view" in session.undo_steps
    assert tuple(state.navigation_location) == (0.0, 0.0, 0.0)
    assert tuple(state.navigation_rotation) == (1.0, 0.0, 0.0, 0.0)
    assert state.navigation_scale == 1.0
    assert bpy.context.scene.camera.matrix_world == camera

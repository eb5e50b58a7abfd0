"""VR controller actions in background Blender (no headset, no session: Blender cannot start
one headless). What Blender itself can check is checked on the running Blender: the data's
enum values against its RNA enums, registration, the action-map sequence against the RNA of the
types it writes, and the operator's edit path on a real scene. A VR session's state is stood in
for by a SimpleNamespace with XrSessionState's attribute names (viewer pose, navigation)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest
from blender_helpers import extension_submodule, forest_world, with_nodes


def _xr_actions():
    return extension_submodule("btf_addon.blender.vr.actions")


def _bindings():
    return extension_submodule("btf_addon.controllers.xr_bindings")


def _is_registered(bpy) -> bool:
    return hasattr(bpy.types, "BTF_OT_xr_action")


@pytest.fixture
def xr_registered(bpy_module, fresh_scene):
    """The VR actions module registered for the test (``blender/vr/preview.py`` may already
    have)."""
    module = _xr_actions()
    ours = not _is_registered(bpy_module)
    if ours:
        module.register()
    yield module
    if ours:
        module.unregister()


def looking_along_y(quaternion_type):
    """A VR pose rotation whose −Z (its forward) is world +Y: 90° about X."""
    return quaternion_type((1.0, 0.0, 0.0), math.pi / 2)


def two_cubes(bpy):
    """Cubes at x = −2 (active) and x = +2, both with "BTF A"; "BTF B" in the file; a forest
    World (its Environment Texture has no Mapping yet)."""
    materials = []
    for name in ("BTF A", "BTF B"):
        mat = with_nodes(bpy.data.materials.new(name))
        mat.btf.enabled = True
        mat.btf.source = f"//{name}.btfm"
        materials.append(mat)
    cubes = []
    for x in (-2.0, 2.0):
        bpy.ops.mesh.primitive_cube_add(size=1.0, location=(x, 0.0, 0.0))
        cube = bpy.context.view_layer.objects.active
        cube.data.materials.append(materials[0])
        cubes.append(cube)
    bpy.context.view_layer.objects.active = cubes[0]
    bpy.context.scene.world = forest_world(bpy, "W")
    bpy.context.view_layer.update()
    return cubes, materials


# ------------------------------------------------------------------ data against RNA
def test_the_data_uses_values_blender_accepts(bpy_module, xr_registered):
    bpy = bpy_module
    xb = _bindings()

    def identifiers(struct, prop):
        return {e.identifier for e in struct.bl_rna.properties[prop].enum_items}

    item_types = identifiers(bpy.types.XrActionMapItem, "type")
    op_modes = identifiers(bpy.types.XrActionMapItem, "op_mode")
    regions = identifiers(bpy.types.XrActionMapBinding, "axis0_region")
    assert regions == identifiers(bpy.types.XrActionMapBinding, "axis1_region")
    op_actions = {
        e.identifier for e in bpy.ops.btf.xr_action.get_rna_type().properties["action"].enum_items
    }
    for item in xb.XR_ACTIONS:
        assert item.type in item_types and item.op_mode in op_modes
        if item.action is not None:
            assert item.action.name in op_actions
            assert item.op == "btf.xr_action"
        for binding in item.bindings:
            assert {binding.axis0_region, binding.axis1_region} <= regions
    assert bpy.app.build_options.xr_openxr  # this Blender has XR: the module is meant for it


# ------------------------------------------------------------------ registration
def test_register_adds_exactly_its_handler_and_operator(bpy_module, fresh_scene):
    bpy = bpy_module
    module = _xr_actions()
    was = _is_registered(bpy)
    if was:
        module.unregister()
    handlers = list(bpy.app.handlers.xr_session_start_pre)
    types, ops = set(dir(bpy.types)), set(dir(bpy.ops.btf))
    try:
        module.register()
        added = [h for h in bpy.app.handlers.xr_session_start_pre if h not in handlers]
        assert added == [module.on_session_start]
        assert len(bpy.app.handlers.xr_session_start_pre) == len(handlers) + 1
        assert hasattr(module.on_session_start, "_bpy_persistent")  # kept on file loads
        assert set(dir(bpy.types)) - types == {"BTF_OT_xr_action"}
        assert set(dir(bpy.ops.btf)) - ops == {"xr_action"}
        # Headless there is no session being started: the handler leaves everything alone.
        assert bpy.context.window_manager.xr_session_state is None
        module.on_session_start(None)
    finally:
        module.unregister()
    assert list(bpy.app.handlers.xr_session_start_pre) == handlers
    assert set(dir(bpy.types)) == types and set(dir(bpy.ops.btf)) == ops
    if was:
        module.register()


def test_the_operator_outside_vr_says_so(bpy_module, xr_registered):
    bpy = bpy_module
    with pytest.raises(RuntimeError, match="come from VR controllers"):
        bpy.ops.btf.xr_action("INVOKE_DEFAULT", action="NEXT_MATERIAL")


# ------------------------------------------------------------------ the action map
class RnaStandIn:
    """Stands in for one RNA struct of the action map: records every attribute write and
    refuses one that Blender's own type would refuse (unknown or read-only property, a value
    outside the enum)."""

    def __init__(self, rna, log, **children) -> None:
        self.__dict__.update(_rna=rna, _log=log, **children)

    def __setattr__(self, name, value) -> None:
        prop = self._rna.properties.get(name)
        assert prop is not None, f"{self._rna.identifier} has no property {name!r}"
        assert not prop.is_readonly, f"{self._rna.identifier}.{name} is read-only"
        if prop.type == "ENUM":
            assert value in {e.identifier for e in prop.enum_items}, (name, value)
        self._log.append(("set", self._rna.identifier, name, value))
        self.__dict__[name] = value


class Collection(list):
    def __init__(self, make) -> None:
        super().__init__()
        self.make = make

    def new(self, *args):
        element = self.make(*args)
        self.append(element)
        return element


class StandInSession:
    """XrSessionState's action-map calls, recorded, refusing what Blender's ``rna_xr.cc``
    refuses (an action without user paths or whose operator is not registered, a binding
    whose component paths do not pair with the user paths); ``refuse`` names a call that
    fails anyway."""

    def __init__(self, bpy, refuse: str = "") -> None:
        types = bpy.types
        self.log: list[tuple] = []
        self.refuse = refuse
        log = self.log

        def path(rna):
            def make(p):
                element = RnaStandIn(rna.bl_rna, log)
                element.path = p
                return element

            return make

        def binding(name, replace):
            assert replace is True
            amb = RnaStandIn(
                types.XrActionMapBinding.bl_rna,
                log,
                component_paths=Collection(path(types.XrComponentPath)),
            )
            amb.name = name
            return amb

        def item(name, replace):
            ami = RnaStandIn(
                types.XrActionMapItem.bl_rna,
                log,
                user_paths=Collection(path(types.XrUserPath)),
                bindings=Collection(binding),
                op_properties=None,
            )
            ami.name = name
            return ami

        def actionmap(state, name, replace):
            assert state is self and replace is True
            am = RnaStandIn(types.XrActionMap.bl_rna, log, actionmap_items=Collection(item))
            am.name = name
            return am

        self.actionmaps = Collection(actionmap)
        self.op_rna = bpy.ops.btf.xr_action.get_rna_type()

    def _call(self, name, *args) -> bool:
        self.log.append((name, *args))
        return name != self.refuse

    def action_set_create(self, context, am):
        return self._call("action_set_create", am.name)

    def action_create(self, context, am, ami):
        import bpy

        assert len(ami.user_paths) >= 1, ami.name
        op = ami.__dict__.get("op", "")
        if op:  # WM_operatortype_find: the operator must be registered
            category, name = op.split(".")
            assert name in dir(getattr(bpy.ops, category)), op
        return self._call("action_create", ami.name)

    def action_binding_create(self, context, am, ami, amb):
        assert len(amb.component_paths) == len(ami.user_paths) >= 1, (ami.name, amb.name)
        return self._call("action_binding_create", ami.name, amb.name)

    def controller_pose_actions_set(self, context, action_set, grip, aim):
        return self._call("controller_pose_actions_set", action_set, grip, aim)

    def active_action_set_set(self, context, action_set):
        return self._call("active_action_set_set", action_set)


def stand_in_op_properties(session, monkeypatch) -> None:
    """Setting ``op`` makes Blender create the operator's properties: stand in for that too."""
    original = RnaStandIn.__setattr__

    def setattr_with_op(self, name, value):
        original(self, name, value)
        if name == "op":
            self.__dict__["op_properties"] = RnaStandIn(session.op_rna, session.log)

    monkeypatch.setattr(RnaStandIn, "__setattr__", setattr_with_op)


def test_action_map_is_built_in_the_add_on_order(bpy_module, xr_registered, monkeypatch):
    bpy = bpy_module
    xb = _bindings()
    session = StandInSession(bpy)
    stand_in_op_properties(session, monkeypatch)
    assert xr_registered.build_action_map(session, bpy.context) is True
    (am,) = session.actionmaps
    assert am.name == xb.ACTION_SET
    assert [ami.name for ami in am.actionmap_items] == [i.name for i in xb.XR_ACTIONS]
    for ami, item in zip(am.actionmap_items, xb.XR_ACTIONS, strict=True):
        assert ami.type == item.type
        assert [p.path for p in ami.user_paths] == list(item.user_paths)
        if item.action is not None:
            assert ami.op == "btf.xr_action" and ami.op_properties.action == item.action.name
            assert ami.op_mode == item.op_mode
        assert [b.profile for b in ami.bindings] == [b.profile for b in item.bindings]
        for amb, binding in zip(ami.bindings, item.bindings, strict=True):
            assert [p.path for p in amb.component_paths] == list(binding.component_paths)
    calls = [entry for entry in session.log if entry[0] != "set"]
    # The add-on's order: the set, then each action followed by its bindings, then the poses,
    # and the active set last.
    expected = [("action_set_create", xb.ACTION_SET)]
    for item in xb.XR_ACTIONS:
        expected.append(("action_create", item.name))
        expected += [("action_binding_create", item.name, b.name) for b in item.bindings]
    expected += [
        ("controller_pose_actions_set", xb.ACTION_SET, "controller_grip", "controller_aim"),
        ("active_action_set_set", xb.ACTION_SET),
    ]
    assert calls == expected


def test_a_refused_binding_stops_before_the_set_is_made_active(
    bpy_module, xr_registered, monkeypatch
):
    bpy = bpy_module
    session = StandInSession(bpy, refuse="action_binding_create")
    stand_in_op_properties(session, monkeypatch)
    assert xr_registered.build_action_map(session, bpy.context) is False
    names = [entry[0] for entry in session.log]
    assert names.count("action_binding_create") == 1 and "active_action_set_set" not in names


# ------------------------------------------------------------------ the operator's edit path
def xr_event(bpy, state=(1.0, 0.0), location=(2.0, -10.0, 0.0), rotation=None):
    """An XrEventData-like value: the state and the aim pose of the controller."""
    from mathutils import Quaternion

    return SimpleNamespace(
        state=state,
        controller_location=location,
        controller_rotation=rotation if rotation is not None else looking_along_y(Quaternion),
        action_set="btf_vr",
        user_path="/user/hand/right",
    )


def test_pointed_material_and_exposure_edits_with_undo_steps(bpy_module, xr_registered):
    bpy = bpy_module
    xb = _bindings()
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    (left, right), (mat_a, mat_b) = two_cubes(bpy)
    bpy.ops.ed.undo_push(message="scene set up")
    ctx = edits.EditContext(bpy.context.scene, bpy.context.view_layer)
    # The right controller at (2, −10, 0) aims along +Y: at the right cube, not the active one.
    run = xr_registered.XrActionRun(ctx, xb.xr_action("next_material"))
    assert run.target(xr_event(bpy)) == right.name
    assert run.press(xr_event(bpy), 0.0) == "material BTF B"
    assert right.material_slots[0].material == mat_b
    assert left.material_slots[0].material == mat_a  # the active object was not touched
    up = xr_registered.XrActionRun(ctx, xb.xr_action("exposure_up"))
    up.press(xr_event(bpy), 0.1)
    assert mat_b.btf.exposure == pytest.approx(1 / 3) and mat_a.btf.exposure == 0.0
    assert run.undo_steps == ["VR: Next material"] and up.undo_steps == ["VR: Exposure +"]
    # Aiming at nothing (along −Y, away from both): the active object's material.
    from mathutils import Quaternion

    away = Quaternion((1.0, 0.0, 0.0), -math.pi / 2)
    assert run.target(xr_event(bpy, rotation=away)) is None
    run.press(xr_event(bpy, rotation=away), 0.2)
    assert left.material_slots[0].material == mat_b
    # The undo steps are real: one each, newest first (undo reloads: look everything up).
    left_name, right_name = left.name, right.name
    bpy.ops.ed.undo()
    assert bpy.data.objects[left_name].material_slots[0].material.name == "BTF A"
    assert bpy.data.materials["BTF B"].btf.exposure == pytest.approx(1 / 3)
    bpy.ops.ed.undo()
    assert bpy.data.materials["BTF B"].btf.exposure == 0.0
    assert bpy.data.objects[right_name].material_slots[0].material.name == "BTF B"
    bpy.ops.ed.undo()
    assert bpy.data.objects[right_name].material_slots[0].material.name == "BTF A"


def test_thumbstick_gesture_rotates_the_world_with_one_undo_step(bpy_module, xr_registered):
    bpy = bpy_module
    xb = _bindings()
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    two_cubes(bpy)
    ctx = edits.EditContext(bpy.context.scene, bpy.context.view_layer)
    run = xr_registered.XrActionRun(ctx, xb.xr_action("rotate_environment"))
    run.press(xr_event(bpy, state=(1.0, 0.0)), 10.0)  # full right from t = 10 s
    run.update(xr_event(bpy, state=(0.5, 0.0)), 10.5)  # 45°/s × 1.0 × 0.5 s = 22.5°
    run.update(xr_event(bpy, state=(0.5, 0.0)), 11.0)  # 45 × 0.5 × 0.5 = 11.25°
    assert run.undo_steps == []  # mid-gesture: no undo step yet
    run.release(xr_event(bpy, state=(0.05, 0.0)), 11.5)  # 45 × 0.5 × 0.5 = 11.25°
    (mapping,) = [
        n for n in bpy.context.scene.world.node_tree.nodes if n.bl_idname == "ShaderNodeMapping"
    ]
    # 45° in all; Blender stores the rotation as float32 (about 1e-7 rad at this size).
    assert mapping.inputs["Rotation"].default_value[2] == pytest.approx(math.radians(45), abs=1e-6)
    assert run.undo_steps == ["VR: Rotate environment"]
    assert len(run.applied) == 3 and all(not e.end for e, _ in run.applied)


def test_reset_action_resets_the_vr_navigation(bpy_module, xr_registered):
    bpy = bpy_module
    from mathutils import Quaternion

    xb = _bindings()
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    two_cubes(bpy)
    state = SimpleNamespace(
        navigation_location=(1.0, 2.0, 3.0),
        navigation_rotation=Quaternion((0.0, 0.0, 1.0), 0.7),
        navigation_scale=0.25,
        viewer_pose_location=(0.0, -5.0, 0.0),
        viewer_pose_rotation=looking_along_y(Quaternion),
    )
    ctx = edits.EditContext(bpy.context.scene, bpy.context.view_layer)
    ctx.xr_source = lambda: state
    run = xr_registered.XrActionRun(ctx, xb.xr_action("reset_navigation"))
    assert run.press(xr_event(bpy), 0.0) == "VR navigation reset"
    assert tuple(state.navigation_location) == (0.0, 0.0, 0.0)
    assert tuple(state.navigation_rotation) == (1.0, 0.0, 0.0, 0.0)
    assert state.navigation_scale == 1.0
    assert run.undo_steps == ["VR: Reset view"]


# ------------------------------------------------------------------ gaze and VR navigation
def nav_matrix(state):
    from mathutils import Matrix, Quaternion, Vector

    s = state.navigation_scale
    return Matrix.LocRotScale(
        Vector(state.navigation_location), Quaternion(state.navigation_rotation), (s, s, s)
    )


def test_gaze_target(bpy_module, fresh_scene):
    bpy = bpy_module
    from mathutils import Quaternion

    pointer = extension_submodule("btf_addon.blender.wiimote.pointer")
    (left, right), _ = two_cubes(bpy)
    scene = bpy.context.scene
    state = SimpleNamespace(
        viewer_pose_location=(2.0, -10.0, 0.0), viewer_pose_rotation=looking_along_y(Quaternion)
    )
    origin, direction = pointer.gaze_ray(state)
    assert tuple(origin) == (2.0, -10.0, 0.0)
    assert tuple(direction) == pytest.approx((0.0, 1.0, 0.0), abs=1e-6)
    assert pointer.object_under_gaze(scene, state) == right.name
    state.viewer_pose_location = (-2.0, -10.0, 0.0)
    assert pointer.object_under_gaze(scene, state) == left.name
    state.viewer_pose_location = (0.0, -10.0, 0.0)  # between the cubes: nothing
    assert pointer.object_under_gaze(scene, state) is None
    # Outside a VR session (headless: none) the Wiimote's edits see no VR state.
    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    assert edits.running_xr_state() is None
    assert edits.EditContext(scene, bpy.context.view_layer).xr() is None


def test_vr_orbit_zoom_and_reset_move_the_navigation(bpy_module, fresh_scene):
    from mathutils import Matrix, Quaternion, Vector

    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    state = SimpleNamespace(
        navigation_location=Vector((0.0, -5.0, 0.0)),
        navigation_rotation=Quaternion(),
        navigation_scale=1.0,
        viewer_pose_location=(0.0, -5.0, 1.6),
        viewer_pose_rotation=looking_along_y(Quaternion),
    )
    pivot = Vector((0.0, 0.0, 0.0))

    def about(pivot, matrix3, scale=1.0):
        """World transform: scale and rotate about the pivot (independent of the module)."""
        m = matrix3.to_4x4() @ Matrix.Scale(scale, 4)
        return Matrix.Translation(pivot) @ m @ Matrix.Translation(-pivot)

    before = nav_matrix(state)
    edits.vr_orbit(state, pivot, 90.0, "YAW")
    # The viewer's world pose is navigation @ (base @ tracked): the whole navigation turns
    # 90° about world Z through the pivot; (0, −5, 0) goes to (5, 0, 0) (to the viewer's right).
    expected = about(pivot, Matrix.Rotation(math.radians(90), 3, "Z")) @ before
    assert tuple(state.navigation_location) == pytest.approx((5.0, 0.0, 0.0), abs=1e-6)
    for a, b in zip(nav_matrix(state), expected, strict=True):
        assert tuple(a) == pytest.approx(tuple(b), abs=1e-6)
    # Pitch +30° with the viewer looking along +Y (its right is +X): the viewer rises.
    state.navigation_location = Vector((0.0, -5.0, 0.0))
    state.navigation_rotation = Quaternion()
    edits.vr_orbit(state, pivot, 30.0, "PITCH")
    assert state.navigation_location.z == pytest.approx(5.0 * math.sin(math.radians(30)))
    # Zoom one stop about a pivot at (1, 0, 0): distance and scale halve.
    state.navigation_location = Vector((1.0, -4.0, 0.0))
    state.navigation_rotation = Quaternion((0.0, 0.0, 1.0), 0.3)
    before = nav_matrix(state)
    edits.vr_zoom(state, Vector((1.0, 0.0, 0.0)), 1.0)
    assert state.navigation_scale == pytest.approx(0.5)
    assert tuple(state.navigation_location) == pytest.approx((1.0, -2.0, 0.0), abs=1e-6)
    expected = about(Vector((1.0, 0.0, 0.0)), Matrix.Identity(3), 0.5) @ before
    for a, b in zip(nav_matrix(state), expected, strict=True):
        assert tuple(a) == pytest.approx(tuple(b), abs=1e-6)
    with pytest.raises(edits.EditSkipped, match="VR scale"):
        edits.vr_zoom(state, pivot, 20.0)  # 2**-20 × 0.5: beyond the kept range
    edits.vr_reset(state)
    assert tuple(state.navigation_location) == (0.0, 0.0, 0.0)
    assert tuple(state.navigation_rotation) == (1.0, 0.0, 0.0, 0.0)
    assert state.navigation_scale == 1.0


def test_view_edits_in_vr_move_the_navigation_not_the_camera(bpy_module, fresh_scene):
    bpy = bpy_module
    from mathutils import Quaternion, Vector

    edits = extension_submodule("btf_addon.blender.wiimote.edits")
    actions = extension_submodule("btf_addon.controllers.actions")
    Action, Edit = actions.Action, actions.Edit  # noqa: N806 - the extension's classes
    two_cubes(bpy)  # the active cube at (−2, 0, 0) is the pivot
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera
    camera_before = camera.matrix_world.copy()
    state = SimpleNamespace(
        navigation_location=Vector((-2.0, -4.0, 0.0)),
        navigation_rotation=Quaternion(),
        navigation_scale=1.0,
        viewer_pose_location=(-2.0, -4.0, 1.6),
        viewer_pose_rotation=looking_along_y(Quaternion),
    )
    ctx = edits.EditContext(bpy.context.scene, bpy.context.view_layer)
    ctx.xr_source = lambda: state
    ctx.save_view()
    edits.apply_edit(ctx, Edit(0.0, Action.ORBIT_CAMERA, 90.0, "YAW"))
    assert tuple(state.navigation_location) == pytest.approx((2.0, 0.0, 0.0), abs=1e-6)
    edits.apply_edit(ctx, Edit(0.0, Action.ZOOM_IN, 1.0))
    assert state.navigation_scale == pytest.approx(0.5)
    assert tuple(state.navigation_location) == pytest.approx((0.0, 0.0, 0.0), abs=1e-6)
    assert edits.apply_edit(ctx, Edit(0.0, Action.RESET_VIEW)) == "VR navigation reset"
    assert state.navigation_scale == 1.0
    assert camera.matrix_world == camera_before  # the scene camera never moved
    # Outside VR the same edit orbits the camera again.
    ctx.xr_source = lambda: None
    edits.apply_edit(ctx, Edit(0.0, Action.ORBIT_CAMERA, 90.0, "YAW"))
    assert camera.matrix_world != camera_before


# ------------------------------------------------------------------ invoke / modal, no window
class StandInWindowManager:
    def __init__(self) -> None:
        self.handlers: list = []

    def modal_handler_add(self, operator) -> bool:
        self.handlers.append(operator)
        return True


def stand_in_operator(module, action: str):
    """The real operator methods on a plain object (Blender runs an operator's invoke and
    modal only with an event, which background Blender never sends)."""
    cls = module.BTF_OT_xr_action
    methods = {name: cls.__dict__[name] for name in ("invoke", "modal", "execute", "_item")}

    def report(self, kind, text) -> None:
        self.reports.append((next(iter(kind)), text))

    operator = type("StandInOperator", (), {**methods, "report": report})()
    operator.action, operator.reports = action, []
    return operator


def xr_action_event(bpy, name: str, value: str, x: float):
    """An Event of type XR_ACTION from the action ``name`` of our set."""
    xr = xr_event(bpy, state=(x, 0.0))
    xr.action = name
    return SimpleNamespace(type="XR_ACTION", value=value, xr=xr)


def test_invoke_and_modal_run_a_thumbstick_gesture(bpy_module, xr_registered, monkeypatch):
    bpy = bpy_module
    two_cubes(bpy)
    clock = [100.0]
    monkeypatch.setattr(xr_registered.time, "monotonic", lambda: clock[0])
    context = SimpleNamespace(
        scene=bpy.context.scene,
        view_layer=bpy.context.view_layer,
        window_manager=StandInWindowManager(),
    )
    operator = stand_in_operator(xr_registered, "ROTATE_ENVIRONMENT")

    def event(value, x, action="rotate_environment"):
        return xr_action_event(bpy, action, value, x)

    assert operator.invoke(context, event("PRESS", 1.0)) == {"RUNNING_MODAL"}
    assert context.window_manager.handlers == [operator]
    clock[0] = 101.0  # one second at full deflection: 45°
    assert operator.modal(context, event("PRESS", -1.0)) == {"RUNNING_MODAL"}
    # Another action's event (e.g. a trigger press meanwhile) is left for its own operator.
    assert operator.modal(context, event("PRESS", 1.0, "next_material")) == {"PASS_THROUGH"}
    assert operator.modal(context, SimpleNamespace(type="MOUSEMOVE", xr=None)) == {"PASS_THROUGH"}
    clock[0] = 101.5  # half a second back at full deflection: −22.5°
    assert operator.modal(context, event("RELEASE", 0.0)) == {"FINISHED"}
    (mapping,) = [
        n for n in bpy.context.scene.world.node_tree.nodes if n.bl_idname == "ShaderNodeMapping"
    ]
    # 45 − 22.5 = 22.5°; float32 storage (about 1e-7 rad).
    rotation_z = mapping.inputs["Rotation"].default_value[2]
    assert rotation_z == pytest.approx(math.radians(22.5), abs=1e-6)
    assert operator._run.undo_steps == ["VR: Rotate environment"]


def test_invoke_applies_a_press_action_at_once(bpy_module, xr_registered):
    bpy = bpy_module
    (_, right), (_, mat_b) = two_cubes(bpy)
    context = SimpleNamespace(
        scene=bpy.context.scene,
        view_layer=bpy.context.view_layer,
        window_manager=StandInWindowManager(),
    )
    operator = stand_in_operator(xr_registered, "NEXT_MATERIAL")
    press = xr_action_event(bpy, "next_material", "PRESS", 1.0)
    assert operator.invoke(context, press) == {"FINISHED"}
    assert context.window_manager.handlers == []  # no modal handler for a press
    assert right.material_slots[0].material == mat_b
    assert operator.reports == [("INFO", "material BTF B")]
    # Without an XR event (a script, a key press): refused with the reason.
    assert operator.invoke(context, SimpleNamespace(type="LEFTMOUSE", xr=None)) == {"CANCELLED"}
    assert "VR controllers" in operator.reports[-1][1]


def test_the_panel_switches_between_our_actions_and_blenders_navigation(bpy_module, xr_registered):
    """Blender syncs one action set at a time: ``activate`` makes ours or the VR add-on's
    (teleport, fly, grab) the active one, and says False without a session."""
    session = StandInSession(bpy_module)
    context = SimpleNamespace(window_manager=SimpleNamespace(xr_session_state=session))
    assert xr_registered.activate(context, use_btf=False) is True
    assert xr_registered.activate(context, use_btf=True) is True
    assert session.log[-2:] == [
        ("active_action_set_set", "blender_default"),
        ("active_action_set_set", _bindings().ACTION_SET),
    ]
    no_session = SimpleNamespace(window_manager=SimpleNamespace(xr_session_state=None))
    assert xr_registered.activate(no_session, use_btf=True) is False


# ------------------------------------------------------------------ beside Blender's navigation
class SessionRefusingDuplicates(StandInSession):
    """As ``StandInSession``, plus what ``WM_xr_action_set_create`` does with a name it has
    (GHOST_XrSession::createActionSet: refused, False) and with actions of a set it lacks
    (refused); the action maps are found by name as ``XrActionMaps.find`` finds them."""

    def __init__(self, bpy) -> None:
        super().__init__(bpy)
        self.sets: list[str] = []
        self.actionmaps.find = lambda state, name: next(
            (am for am in self.actionmaps if am.name == name), None
        )

    def action_set_create(self, context, am):
        if am.name in self.sets:
            self.log.append(("action_set_create refused", am.name))
            return False
        self.sets.append(am.name)
        return super().action_set_create(context, am)

    def action_create(self, context, am, ami):
        return am.name in self.sets and super().action_create(context, am, ami)


def vr_scene_inspection_handler(session):
    """The VR Scene Inspection add-on's ``xr_session_start_pre`` handler as its
    ``action_map.py`` ``vr_create_actions`` runs it: ensure its two default maps, then walk EVERY
    action map of the session, giving up at the first ``action_set_create`` that fails, then
    make the first map's set the active one."""

    def vr_create_actions(context):  # one argument: Blender passes it one (choose_arguments)
        for name in ("blender_default", "blender_default_gamepad"):
            if session.actionmaps.find(session, name) is None:
                am = session.actionmaps.new(session, name, True)
                ami = am.actionmap_items.new("teleport", True)
                ami.user_paths.new("/user/hand/left")
                amb = ami.bindings.new("oculus", True)
                amb.component_paths.new("/input/trigger/value")
        for am in session.actionmaps:
            if not session.action_set_create(None, am):
                return
            for ami in am.actionmap_items:
                if not session.action_create(None, am, ami):
                    return
        session.active_action_set_set(None, session.actionmaps[0].name)

    return vr_create_actions


def run_start_pre_handlers(handlers) -> None:
    """Blender's handler loop (bpy_app_generic_callback): the list's length is read at every
    step, a function of one positional argument gets one argument, others get two."""
    pos = 0
    while pos < len(handlers):
        func = handlers[pos]
        code = getattr(func, "__code__", None)
        func(*((None,) if code is not None and code.co_argcount == 1 else (None, None)))
        pos += 1


@pytest.mark.parametrize("ours_first", [True, False])
def test_blenders_navigation_is_created_whichever_handler_runs_first(
    bpy_module, xr_registered, monkeypatch, ours_first
):
    """Issue 35 item 1: whether our handler was added before or after the VR add-on's, the
    add-on creates its sets (teleport, fly, grab stay available) and ours is created too, last,
    and is the active set."""
    bpy = bpy_module
    xb = _bindings()
    session = SessionRefusingDuplicates(bpy)
    stand_in_op_properties(session, monkeypatch)
    monkeypatch.setattr(xr_registered, "_session_state", lambda context: session)
    handlers = bpy.app.handlers.xr_session_start_pre
    saved = list(handlers)
    addon = vr_scene_inspection_handler(session)
    order = [xr_registered.on_session_start, addon]
    try:
        handlers.clear()
        handlers.extend(order if ours_first else order[::-1])
        run_start_pre_handlers(handlers)
        after = list(handlers)
    finally:
        handlers.clear()
        handlers.extend(saved)
    refused = [e for e in session.log if e[0] == "action_set_create refused"]
    assert refused == []
    assert session.sets == ["blender_default", "blender_default_gamepad", xb.ACTION_SET]
    actives = [e[1] for e in session.log if e[0] == "active_action_set_set"]
    assert actives[-1] == xb.ACTION_SET
    assert after == (order if ours_first else order[::-1])  # the one-shot builder is gone

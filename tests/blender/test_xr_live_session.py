"""Blender's VR session as it really runs (issue 35), with stand-ins that behave as Blender's
source does: the session drawn from the window it was started from (``wm_xr_session.cc``
``wm_xr_session_root_window_or_fallback_get``), the viewer pose that reads (0, 0, 0) until the
first eye was drawn, view matrices that divide by base scale × navigation scale
(``wm_xr_draw.cc`` ``wm_xr_draw_matrices_create``), the VR add-on's own Start button that leaves
custom overlays off, and a missing runtime reported by Blender's XR error handler."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from blender_helpers import extension_submodule


def _sibling(name: str):
    """A sibling test module (pytest runs with --import-mode=importlib: no plain import)."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


_draw = _sibling("test_xr_draw")
HEAD, EyeTargets, eyes, new_preview = _draw.HEAD, _draw.EyeTargets, _draw.eyes, _draw.new_preview
stand_in_session = _draw.stand_in_session
vr_scene = _draw.vr_scene  # the fixture


def _preview_module():
    return extension_submodule("btf_addon.blender.vr.preview")


# ------------------------------------------------------------------ item 5: the session's window
class StandInWindow(SimpleNamespace):
    def as_pointer(self) -> int:
        return self.pointer


def test_the_session_draws_the_scene_of_the_window_it_was_started_from(bpy_module, installed):
    """Two windows with different view layers: the session started from the second draws the
    second's; once that window is closed, Blender falls back to the first window."""
    xr = _preview_module()
    first = StandInWindow(pointer=101, view_layer=SimpleNamespace(depsgraph="first's"))
    second = StandInWindow(pointer=202, view_layer=SimpleNamespace(depsgraph="second's"))
    wm = SimpleNamespace(windows=[first, second], xr_session_state=None)
    saved = xr._session_window_id
    try:
        xr.remember_session_window(SimpleNamespace(window=second))
        source = xr.session_source(lambda: wm)
        assert source.depsgraph() == "second's"
        wm.windows = [first]  # the session's window closed
        assert source.depsgraph() == "first's"
    finally:
        xr._session_window_id = saved


# ------------------------------------------------------------------ item 7: the start-up gap
def mirror_view(head=HEAD, target=(0.0, 0.0, 0.0), width=96, height=72):
    """A desktop "Mirror VR Session" view: the viewer pose's camera, a symmetric frustum, the
    window's size (bigger than the eyes here)."""
    look_at = extension_submodule("btf_addon.scene.scene").look_at
    view_from_world = np.linalg.inv(look_at(head, target))
    near, far, t = 0.1, 100.0, 0.5
    a = width / height
    clip_from_view = np.array(
        [
            [1 / (a * t), 0, 0, 0],
            [0, 1 / t, 0, 0],
            [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
            [0, 0, -1, 0],
        ]
    )
    return SimpleNamespace(
        width=width, height=height, clip_from_view=clip_from_view, view_from_world=view_from_world
    )


def test_a_mirror_draw_before_the_first_eye_is_not_filed_as_an_eye(bpy_module, vr_scene):
    """Until the first eye is drawn Blender's ``viewer_pose_location`` reads (0, 0, 0): a mirror
    draw then (window size, symmetric frustum) must not become "left" or "right", whose
    accumulation would be resized to the window and whose budget would count it."""
    bpy = bpy_module
    head = (1.0, -5.0, 1.2)
    _, eye_list = eyes(head=head)
    session = SimpleNamespace(viewer_pose_location=(0.0, 0.0, 0.0), navigation_scale=1.0)
    preview = new_preview(bpy, session)
    mirror = mirror_view(head, target=(2.0, 0.0, 0.0))  # its +x does not pass the origin
    mirror_target = EyeTargets([mirror])
    targets = EyeTargets(eye_list)
    try:
        mirror_target.frame(preview)
        assert not {"left", "right"} & set(preview.eyes), preview.last_eye
        session.viewer_pose_location = head  # the first eye's draw sets the pose
        targets.frame(preview)
        assert {"left", "right"} <= set(preview.eyes)
        for key, eye in zip(("left", "right"), eye_list, strict=True):
            assert preview.eyes[key].view.size == (eye.width, eye.height), key
    finally:
        preview.release()
        targets.free()
        mirror_target.free()


# ------------------------------------------------------------------ item 6: HUD in metres
def scaled_session_eyes(base_scale: float, nav_scale: float):
    """The two eyes' matrices as Blender makes them with a base pose and a navigation of their
    own scale: world_from_view = nav · base · eye (each ``wm_xr_pose_scale_to_mat``), and the
    viewer pose in world space through the same transforms."""
    profile, _ = eyes()
    look_at = extension_submodule("btf_addon.scene.scene").look_at

    def pose(location, scale, angle):
        c, s = np.cos(angle), np.sin(angle)
        m = np.eye(4)
        m[:3, :3] = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) * scale
        m[:3, 3] = location
        return m

    nav = pose((1.0, -6.0, 0.4), nav_scale, 0.3)
    base = pose((0.2, 0.1, 1.0), base_scale, -0.2)
    world_from_tracking = nav @ base
    head_tracking = look_at((0.0, -0.2, 0.0), (0.0, 1.0, 0.0))
    eye_list = extension_submodule("btf_addon.render.headsets").stereo_eyes(profile, head_tracking)
    scaled = []
    for eye in eye_list:
        world_from_view = world_from_tracking @ np.linalg.inv(eye.view_from_world)
        scaled.append(
            SimpleNamespace(
                width=eye.width,
                height=eye.height,
                clip_from_view=eye.clip_from_view,
                view_from_world=np.linalg.inv(world_from_view),
            )
        )
    viewer = (world_from_tracking @ head_tracking[:, 3])[:3]
    return scaled, viewer


@pytest.mark.parametrize(("base_scale", "nav_scale"), [(1.0, 1.0), (2.5, 1.0), (1.0, 100.0)])
def test_the_hud_sits_in_headset_metres_whatever_the_scales(
    bpy_module, vr_scene, monkeypatch, base_scale, nav_scale
):
    """Blender's view space is metres whatever the base and navigation scales: the HUD quad is
    1.2 m ahead in each eye's view space (not 1.2 × scale: at the default clip end it would
    vanish above ~83×), and both eyes' quads are ONE quad in the world (they fuse)."""
    bpy = bpy_module
    hud = extension_submodule("btf_addon.gl.hud")
    drawn = []
    original = hud.HudDrawer.draw

    def record(self, clip_from_view, corners):
        drawn.append(np.array(corners, dtype=np.float64))
        original(self, clip_from_view, corners)

    monkeypatch.setattr(hud.HudDrawer, "draw", record)
    vr_scene.btf_vr.show_hud = True
    eye_list, viewer = scaled_session_eyes(base_scale, nav_scale)
    session = SimpleNamespace(viewer_pose_location=tuple(viewer), navigation_scale=nav_scale)
    preview = new_preview(bpy, session)
    targets = EyeTargets(eye_list)
    try:
        targets.frame(preview)
    finally:
        preview.release()
        targets.free()
    assert len(drawn) == 2
    world = []
    for corners, eye in zip(drawn, eye_list, strict=True):
        assert np.allclose(corners[:, 2], -1.2, atol=1e-9), corners
        world_from_view = np.linalg.inv(eye.view_from_world)
        world.append((world_from_view @ np.c_[corners, np.ones(4)].T).T[:, :3])
    scale = base_scale * nav_scale
    assert np.abs(world[0] - world[1]).max() < 1e-4 * scale, (world[0], world[1])


# ------------------------------------------------------------------ item 8: overlays, failed start
def _panel_module():
    return extension_submodule("btf_addon.blender.vr.panel")


def draw_vr_panel(bpy):
    layout = _sibling("test_panels").RecordingLayout()
    bpy.types.VIEW3D_PT_btf_vr.draw(SimpleNamespace(layout=layout), bpy.context)
    return layout


class OperatorStandIn(SimpleNamespace):
    """``self`` of an operator's execute: records its reports."""

    def report(self, kind, text) -> None:
        self.reports.append((next(iter(kind)), text))


def test_one_click_turns_custom_overlays_on(bpy_module, fresh_scene):
    """A session started from the VR add-on's own button leaves Custom Overlays off (our
    drawing is one): the panel's warning carries the operator that turns them on."""
    bpy = bpy_module
    settings = bpy.context.window_manager.xr_session_settings
    settings.show_custom_overlays = False
    try:
        assert "btf.vr_show_custom_overlays" in draw_vr_panel(bpy).operators
        assert bpy.ops.btf.vr_show_custom_overlays() == {"FINISHED"}
        assert settings.show_custom_overlays is True
        assert "btf.vr_show_custom_overlays" not in draw_vr_panel(bpy).operators
    finally:
        settings.show_custom_overlays = True


def test_a_start_blender_refused_is_explained_in_blenders_words(
    bpy_module, fresh_scene, monkeypatch
):
    """No runtime: Blender's XR error handler reports "Failed to connect to an OpenXR runtime."
    itself and ``wm.xr_session_toggle`` returns CANCELLED without raising. Our operator adds no
    report over Blender's message; the panel explains Blender's messages. Without a window the
    toggle's poll fails (a RuntimeError): that is said as such, not as a missing runtime."""
    bpy = bpy_module
    panel = _panel_module()
    monkeypatch.setattr(panel, "last_start_failed", False)
    monkeypatch.setattr(panel, "_xr_session_toggle", lambda context: {"CANCELLED"})
    op = OperatorStandIn(reports=[])
    assert panel.BTF_OT_vr_session_toggle.execute(op, bpy.context) == {"CANCELLED"}
    assert op.reports == []
    labels = draw_vr_panel(bpy).labels
    assert any("Failed to connect to an OpenXR runtime." in line for line in labels), labels
    monkeypatch.undo()
    monkeypatch.setattr(panel, "last_start_failed", False)
    op = OperatorStandIn(reports=[])
    assert panel.BTF_OT_vr_session_toggle.execute(op, bpy.context) == {"CANCELLED"}
    assert op.reports == [("ERROR", panel.NO_WINDOW)]


# ------------------------------------------------------------------ item 4: live-use costs
def test_a_mirror_view_neither_counts_as_an_eye_frame_nor_eats_the_eyes_budget(
    bpy_module, vr_scene, monkeypatch
):
    """A desktop "Mirror VR Session" runs the callback a third time per frame at window size.
    An eye costing 2 ms + 3 ms per light against the 11 ms budget settles at 3 lights a frame
    whether or not a mirror draw taking 10 ms lies between their frames; the mirror is a view
    of its own, never "left" or "right"."""
    bpy = bpy_module
    drawer_module = extension_submodule("btf_addon.gl.drawer")
    vr_scene.btf_vr.lights_mode = "BUDGET"
    vr_scene.btf_vr.lights_total = 4096  # never converges during the test
    _, eye_list = eyes()
    eye_list = eye_list[:1]  # as in test_xr_draw's budget test: the left eye's own costs
    mirror = mirror_view()
    clock = SimpleNamespace(t=0.0)
    original = drawer_module.ProgressiveDrawer.draw_resolved

    def draw_resolved(self, view, *args, **kwargs):
        if view.size == (mirror.width, mirror.height):
            clock.t += 0.010  # the window-sized draw's time, inside the callback
        return original(self, view, *args, **kwargs)

    monkeypatch.setattr(drawer_module.ProgressiveDrawer, "draw_resolved", draw_resolved)
    preview = new_preview(bpy, stand_in_session(), clock=lambda: clock.t)
    targets = EyeTargets(eye_list)
    mirror_target = EyeTargets([mirror])
    try:
        for _ in range(30):
            mirror_target.frame(preview)
            state = preview.eyes.get("left")
            clock.t += 0.002 + 0.003 * (state.drawn if state else 0)
            targets.frame(preview)
        budget = preview.eyes["left"].budget
        assert budget.lights_per_frame == 3 and not budget.over_budget, budget.status()
        assert set(preview.eyes) == {"left", "mirror"}
        assert preview.eyes["mirror"].view.size == (mirror.width, mirror.height)
    finally:
        preview.release()
        targets.free()
        mirror_target.free()


def test_the_gaze_is_cast_once_per_head_pose_not_per_eye_restart(bpy_module, vr_scene):
    """The HUD's gaze material: one ray cast for both eyes, again only once the head moved
    more than 1 cm (here: 2 mm per frame for four frames, then 5 cm)."""
    bpy = bpy_module
    vr_scene.btf_vr.show_hud = True
    preview = new_preview(bpy, stand_in_session())
    _, eye_list = eyes()
    targets = EyeTargets(eye_list)
    try:
        for step in range(4):
            head = (HEAD[0] + 0.002 * step, HEAD[1], HEAD[2])
            preview.source = type(preview.source)(
                preview.source.depsgraph, lambda head=head: stand_in_session(head)
            )
            targets.frame(preview, eyes(head=head)[1])
        assert preview.ray_casts == 1
        assert preview.gaze.material == "BTF"  # the sphere straight ahead
        head = (HEAD[0] + 0.05, HEAD[1], HEAD[2])
        preview.source = type(preview.source)(
            preview.source.depsgraph, lambda: stand_in_session(head)
        )
        targets.frame(preview, eyes(head=head)[1])
        assert preview.ray_casts == 2
    finally:
        preview.release()
        targets.free()


def test_only_updates_of_drawn_data_rebuild_the_drawer(bpy_module, vr_scene):
    """Blender's own updates for a moved camera or a Scene property (our VR exposure, read
    every frame) leave the drawer and the eyes' accumulations alone; an object, a material or
    the World rebuild it. The camera's real depsgraph updates are checked too."""
    bpy = bpy_module
    live = extension_submodule("btf_addon.blender.vr.live")
    seen = []
    bpy.context.view_layer.update()  # the fixture's own changes evaluated first

    def record(scene, depsgraph):
        seen.append([SimpleNamespace(id=u.id.original) for u in depsgraph.updates])

    bpy.app.handlers.depsgraph_update_post.append(record)
    try:
        vr_scene.camera.location.x += 0.5
        bpy.context.view_layer.update()
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(record)
    assert seen and all(not live.drawn_data_changed(updates) for updates in seen), [
        [type(u.id).__name__ for u in updates] for updates in seen
    ]

    def updates(*ids):
        flags = dict(is_updated_geometry=False, is_updated_shading=False)
        return SimpleNamespace(updates=[SimpleNamespace(id=i, **flags) for i in ids])

    camera = bpy.data.objects.new("VR cam", bpy.data.cameras.new("VR cam"))
    preview = new_preview(bpy, stand_in_session())
    _, eye_list = eyes()
    targets = EyeTargets(eye_list)
    try:
        targets.frame(preview)
        drawer = preview.drawer
        for still in (updates(vr_scene), updates(camera), updates(vr_scene, camera.data)):
            preview.depsgraph_updated(still)
            assert not preview.scene_dirty
        targets.frame(preview)
        assert preview.drawer is drawer
        assert all(e.view.state.done == 14 for e in preview.eyes.values())  # 7 + 7: no restart
        for changed in (
            updates(bpy.data.objects["Cube"]),
            updates(bpy.data.materials["Red"]),
            updates(vr_scene.world),
        ):
            preview.scene_dirty = False
            preview.depsgraph_updated(changed)
            assert preview.scene_dirty
    finally:
        preview.release()
        targets.free()
        bpy.data.objects.remove(camera)


def test_uniforms_are_converted_once_not_per_mesh_draw(bpy_module, vr_scene):
    """Each mesh is drawn a few times per eye per frame with the same matrices: the device
    converts each distinct uniform value once (a still head: the second frame's draws find
    nearly all of them converted already)."""
    bpy = bpy_module
    preview = new_preview(bpy, stand_in_session())
    device = preview.device
    calls = SimpleNamespace(draws=0)
    original = type(device).draw

    def counting_draw(program, vertices, uniforms, samplers):
        calls.draws += len(uniforms)
        return original(device, program, vertices, uniforms, samplers)

    device.draw = counting_draw
    _, eye_list = eyes()
    targets = EyeTargets(eye_list)
    try:
        targets.frame(preview)
        before, draws_before = device.conversions, calls.draws
        targets.frame(preview)
        converted, uniforms_set = device.conversions - before, calls.draws - draws_before
    finally:
        preview.release()
        targets.free()
    # A draw per material and pass (gl/drawer.py batches a material's meshes): still a dozen
    # uniforms set per eye frame, most of them values converted the frame before.
    assert uniforms_set >= 12
    assert converted <= uniforms_set / 4, (converted, uniforms_set)


# ------------------------------------------------------------------ item 2: the desktop's colours
def srgb_encode(v):
    v = np.clip(v, 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)


def srgb_decode(v):
    return np.where(v <= 0.04045, v / 12.92, np.power((v + 0.055) / 1.055, 2.4))


def blender_overlay_merge(drawn: np.ndarray) -> np.ndarray:
    """What the headset shows for an opaque overlay pixel: our output stored in Blender's
    8-bit sRGB overlay texture (encoded, rounded to 8 bits, decoded when sampled), then
    ``OCIO_ProcessColor``'s merge: col = col·(1 − a) + overlay, col = pow(col, 1/2.2)."""
    stored = np.round(srgb_encode(drawn) * 255.0) / 255.0
    return np.power(srgb_decode(stored), 1 / 2.2)


@pytest.mark.parametrize(("view_transform", "exposure"), [("Standard", 1.0), ("AgX", 0.0)])
def test_the_eyes_show_the_desktops_colours_through_the_8bit_srgb_overlay(
    bpy_module, vr_scene, view_transform, exposure
):
    """Blender merges our image over its own AFTER its view transform, from an 8-bit sRGB
    overlay buffer: drawn through the scene's view transform (Standard with +1 stop; AgX), an
    eye shows, after Blender's merge, the display values Blender gives the same radiance (the
    standalone renderer's image): sRGB-encoded 2 × radiance for Standard, Blender's own AgX
    output (``save_render`` of those very pixels) for AgX. Tolerance: the 65³ LUT's trilinear
    interpolation over 0.34-stop nodes and the 8-bit storage, 0.03 at most, 0.006 on average."""
    bpy = bpy_module
    display_module = extension_submodule("btf_addon.blender.vr.display")
    xr = _preview_module()
    vr_scene.view_settings.view_transform = view_transform
    vr_scene.view_settings.exposure = exposure
    display = display_module.DisplayTransform()
    display.update(vr_scene)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    preview = xr.XRPreview(
        xr.SceneSource(lambda: depsgraph, lambda: stand_in_session()), display=display
    )
    _, eye_list = eyes()
    targets = EyeTargets(eye_list[:1])
    try:
        for _ in range(4):
            targets.frame(preview)
        (drawn,) = targets.read()
    finally:
        preview.release()
        targets.free()
    (reference,) = _draw.reference_images(bpy, eye_list[:1], 24)
    shown = blender_overlay_merge(drawn[..., :3])
    if view_transform == "Standard":
        expected = srgb_encode(reference[..., :3] * 2.0**exposure)
    else:
        expected = display_module.display_values(vr_scene, reference[..., :3]).reshape(
            (*reference.shape[:2], 3)
        )
    error = np.abs(shown - expected)
    assert error.max() < 0.03 and error.mean() < 0.006, (error.max(), error.mean())
    untransformed = blender_overlay_merge(np.clip(reference[..., :3], 0.0, 1.0))
    assert np.abs(untransformed - expected).mean() > 0.03  # what the eyes showed before


# ------------------------------------------------------------------ item 3: Blender's controllers
def test_session_start_puts_our_callback_before_blenders_controllers(bpy_module, installed):
    """Blender appends its controller stand-ins' and aim rays' 'XR' callback when a session
    sets up its controller data, after ``xr_session_start_pre``. Our callback, re-added at the
    end of the list in that handler, comes before it in every session, also when the add-on was
    enabled while another session ran (then ours was added after Blender's and hid them)."""
    bpy = bpy_module
    preview = _preview_module()
    assert preview._handler is not None  # the pip bpy is built with OpenXR
    before = preview._handler
    preview._on_session_start()
    after = preview._handler
    assert after is not before
    with pytest.raises(ValueError):  # the old registration is gone: removing it again fails
        bpy.types.SpaceView3D.draw_handler_remove(before, "XR")


def test_both_eyes_of_blenders_session_share_one_budget_decision(bpy_module, vr_scene):
    """Issue 30 item 6 in Blender's VR session: the eyes of a frame get the same lights per
    frame although the left eye costs ten times as much per light (the mirror keeps its own)."""
    bpy = bpy_module
    vr_scene.btf_vr.lights_mode = "BUDGET"
    vr_scene.btf_vr.lights_total = 4096  # never converges during the test
    _, eye_list = eyes()
    clock = SimpleNamespace(t=0.0)
    preview = new_preview(bpy, stand_in_session(), clock=lambda: clock.t)
    targets = [EyeTargets([e]) for e in eye_list]
    ks = []
    try:
        for _ in range(30):
            for side, target in zip(("left", "right"), targets, strict=True):
                state = preview.eyes.get(side)
                per_light = 0.003 if side == "left" else 0.0003
                clock.t += 0.001 + per_light * (state.drawn if state else 0)
                target.frame(preview)
            ks.append((preview.eyes["left"].drawn, preview.eyes["right"].drawn))
        assert preview.eyes["left"].shared is preview.eyes["right"].shared is preview.shared
        assert all(left == right for left, right in ks[1:]), ks
        assert max(k for k, _ in ks) > 1  # the budget did decide, it is not stuck at one light
    finally:
        preview.release()
        for target in targets:
            target.free()

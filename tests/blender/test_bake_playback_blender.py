"""The light bake in Blender's drawers (issue 34): the viewport plays back the bake the
operator wrote (its relative path on ``scene.btf_bake``), through Blender's gpu module, as the
standalone moderngl drawer plays back the same export; moving an object makes its bake stale
and the panel says so; a missing bake lights everything live with a message."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from blender_helpers import (
    draw_panel,
    extension_submodule,
    init_gpu_module,
    sphere_on_ground,
    stand_in_engine,
)
from helpers import run_cli

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container

pytestmark = pytest.mark.opencl

W, H = 64, 48


def _baked_scene(bpy, tmp_path):
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (W, H), 16, 8)
    scene.btf_bake.spacing, scene.btf_bake.view_bins, scene.btf_bake.samples = 0.5, 2, 16
    scene.btf_render.lights_total = scene.btf_render.lights_per_redraw = 4
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    assert bpy.ops.btf.bake_light() == {"FINISHED"}
    return scene


def _camera_context(exported):
    import mathutils

    cam = exported.camera
    region_data = SimpleNamespace(
        perspective_matrix=mathutils.Matrix(cam.clip_from_world(W / H).tolist()),
        view_matrix=mathutils.Matrix(np.linalg.inv(cam.world_from_camera).tolist()),
        is_perspective=True,
    )
    return SimpleNamespace(region=SimpleNamespace(width=W, height=H), region_data=region_data)


def _draw(bpy, engine, context):
    viewport = extension_submodule("btf_addon.blender.viewport")
    depsgraph = bpy.context.evaluated_depsgraph_get()
    viewport.view_update(engine, context, depsgraph)
    viewport.view_draw(engine, context, depsgraph)
    state = engine.btf_viewport
    assert engine.reports == [] and state.view.state.converged
    return state.view.read()[::-1, :, :3]


def test_the_viewport_plays_back_the_operators_bake(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    export = extension_submodule("btf_addon.blender.export")
    bake_export = extension_submodule("btf_addon.blender.export.light_bake")
    operator = extension_submodule("btf_addon.blender.bake.operator")
    renderer = extension_submodule("btf_addon.gl.renderer")
    init_gpu_module(bpy)
    scene = _baked_scene(bpy, tmp_path)
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get(), W, H, viewport=True)
    assert exported.light_bake is not None  # read from the scene's relative path
    engine, context = stand_in_engine(), _camera_context(exported)
    drawn = _draw(bpy, engine, context)
    names = [m.name for m in exported.meshes]
    assert engine.btf_viewport.drawer.bake_status.played == tuple(names)
    status = bake_export.last_status(scene)
    assert status.startswith("Light bake: baked light on ") and "stale" not in status
    assert status in draw_panel(operator.BTF_PT_render_light_bake, bpy.context).labels

    # The same export through the standalone moderngl drawer (the same virtual lights: the
    # baked meshes do not depend on them; the World behind does not either).
    lighting = extension_submodule("btf_addon.render.lighting")
    settings = extension_submodule("btf_addon.render.settings").RenderSettings
    lights = lighting.frame_lights(
        settings.from_properties(scene.btf_render),
        exported,
        exported.camera.world_from_camera[:3, 2],
    )
    standalone = renderer.GLSLRenderer(exported, W, H)
    standalone.view.jitter = engine.btf_viewport.view.jitter
    try:
        reference = standalone.render(lights, per_pass=4)
    finally:
        standalone.release()
        init_gpu_module(bpy)
    # Half-float viewport target (2⁻¹¹ relative) and two pipelines' float32 rounding, as
    # tests/blender/test_viewport_draw.py bounds the live drawing.
    error = np.abs(drawn - reference)
    assert error.max() < 1e-3 * reference.max(), error.max() / reference.max()

    # The sphere moves: both bakes are stale (it shadowed the ground), drawn with live light.
    sphere = next(o for o in scene.objects if o.type == "MESH" and "Sphere" in o.name)
    sphere.location.x += 0.5
    bpy.context.view_layer.update()
    # what view_update records when Blender reports the move (its updates are only readable
    # inside Blender's own update callback, which a background test does not get)
    engine.btf_viewport.scene_dirty = True
    moved = _draw(bpy, engine, context)
    status = bake_export.last_status(scene)
    assert "stale, live light on " in status and "bake again" in status, status
    assert engine.btf_viewport.drawer.bake_status.played == ()
    assert np.abs(moved - drawn).mean() > 1e-3


def test_a_bake_from_the_command_line_is_found_beside_the_blend(bpy_module, fresh_scene, tmp_path):
    """A farm bakes with ``python -m btf_addon bake``, which writes beside the .blend and does
    not touch the file: the scene (no bake path) finds that bake at its default place."""
    bpy = bpy_module
    export = extension_submodule("btf_addon.blender.export")
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (W, H), 16, 8)
    blend = tmp_path / "farm.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert export.export_scene(depsgraph, W, H, viewport=True).light_bake is None  # none yet
    args = ("--spacing", "0.5", "--view-bins", "2", "--samples", "16")
    run_cli("bake", "--blend", blend, *args)
    assert bpy.context.scene.btf_bake.path == ""  # the file was not changed
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get(), W, H, viewport=True)
    assert exported.light_bake is not None
    assert [m.baked for m in exported.light_bake.meshes] == [True, True]


def test_a_missing_bake_lights_everything_live_and_says_so(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    export = extension_submodule("btf_addon.blender.export")
    scene = _baked_scene(bpy, tmp_path)
    (tmp_path / scene.btf_bake.path.removeprefix("//")).unlink()
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get(), W, H, viewport=True)
    assert exported.light_bake is None
    assert any("is missing" in m and "bake again" in m for m in exported.messages)

"""The viewport's view_update/view_draw logic, driven with a stand-in engine and 3D-view matrices.

Background Blender has no 3D view, so the engine's display-space shader (colour management of
the final blit) cannot be bound: the stand-in engine skips that one call, everything else —
export, uploads, progressive accumulation, restarts, redraw requests — runs for real, and what
it draws is compared with the standalone moderngl renderer."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from blender_helpers import (
    extension_submodule,
    init_gpu_module,
    sphere_on_ground,
    stand_in_engine,
    view_context,
)


def test_progressive_viewport_accumulates_and_restarts(bpy_module, fresh_scene):
    bpy = bpy_module
    viewport = extension_submodule("btf_addon.blender.viewport")
    init_gpu_module(bpy)
    bpy.ops.mesh.primitive_uv_sphere_add()  # no camera: the viewport does not need one
    settings = bpy.context.scene.btf_render
    settings.lights_total, settings.lights_per_redraw = 12, 5
    engine, context = stand_in_engine(), view_context(5.0)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    viewport.view_update(engine, context, depsgraph)

    viewport.view_draw(engine, context, depsgraph)
    state = engine.btf_viewport
    assert engine.reports == [] and state.view.state.done == 5 and engine.redraws == 1
    viewport.view_draw(engine, context, depsgraph)
    viewport.view_draw(engine, context, depsgraph)  # 5 + 5 + 2: converged, no more redraws
    assert state.view.state.done == 12 and state.view.state.converged
    assert engine.redraws == 2
    image = state.view.read()
    assert np.all(np.isfinite(image)) and image.max() > 0

    moved = view_context(4.0)  # the view changed: accumulation restarts, nothing re-exported
    drawer = state.drawer
    viewport.view_draw(engine, moved, depsgraph)
    assert state.drawer is drawer and state.view.state.done == 5

    settings.lights_per_redraw = 3  # a setting changed: restart with the new K
    viewport.view_draw(engine, moved, depsgraph)
    assert state.view.state.done == 3


def lit_scene(bpy, tmp_path):
    """A GGX sphere (a .btfm container), a plain diffuse ground, a point light, the forest
    World and a camera: every input of the drawer (two materials' tables, Blender's lights,
    the environment's bilinear lookups behind the objects)."""
    from btf_addon.core.codecs.analytic import GGXBTF
    from btf_addon.core.formats.container import write_container

    write_container(tmp_path / "ggx.btfm", GGXBTF((0.9, 0.6, 0.3), 0.4))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "ggx.btfm", segments=32, rings=16)
    light = bpy.data.objects.new("Point", bpy.data.lights.new("Point", "POINT"))
    light.data.energy = 300.0
    light.location = (2.0, -2.0, 2.0)
    scene.collection.objects.link(light)
    return scene


def test_viewport_draws_what_the_standalone_renderer_draws(bpy_module, fresh_scene, tmp_path):
    """Blender's gpu pipeline (the viewport, K lights per redraw until converged) against the
    standalone moderngl renderer (the same batches) on the same exported scene, seen from
    the scene camera's matrices, with the same virtual lights and the same jitter per batch."""
    import mathutils

    bpy = bpy_module
    viewport = extension_submodule("btf_addon.blender.viewport")
    export = extension_submodule("btf_addon.blender.export")
    lighting = extension_submodule("btf_addon.render.lighting")
    settings_module = extension_submodule("btf_addon.render.settings")
    renderer = extension_submodule("btf_addon.gl.renderer")
    init_gpu_module(bpy)
    scene = lit_scene(bpy, tmp_path)
    scene.btf_render.lights_total, scene.btf_render.lights_per_redraw = 24, 7
    w, h = 64, 48
    depsgraph = bpy.context.evaluated_depsgraph_get()
    exported = export.export_scene(depsgraph, w, h, viewport=True)
    cam = exported.camera
    view_matrix = np.linalg.inv(cam.world_from_camera)
    region_data = SimpleNamespace(
        perspective_matrix=mathutils.Matrix(cam.clip_from_world(w / h).tolist()),
        view_matrix=mathutils.Matrix(view_matrix.tolist()),
        is_perspective=True,
    )
    context = SimpleNamespace(region=SimpleNamespace(width=w, height=h), region_data=region_data)
    engine = stand_in_engine()
    viewport.view_update(engine, context, depsgraph)
    for _ in range(4):  # 7 + 7 + 7 + 3
        viewport.view_draw(engine, context, depsgraph)
    state = engine.btf_viewport
    assert engine.reports == [] and state.view.state.converged and engine.redraws == 3
    drawn = state.view.read()[::-1, :, :3]  # the viewport's output, row 0 at the top
    assert len(state.drawer.scene.lights) == 1 and len(state.drawer.scene.materials) == 2

    # Blender's gpu drawing is done: the moderngl context made current below cannot disturb it.
    settings = settings_module.RenderSettings.from_properties(scene.btf_render)
    lights = lighting.frame_lights(settings, exported, cam.world_from_camera[:3, 2])
    standalone = renderer.GLSLRenderer(exported, w, h)
    standalone.view.jitter = settings.film()  # the same subpixel offset per batch of 7
    try:
        reference = standalone.render(lights, per_pass=7)
    finally:
        standalone.release()  # leaves no OpenGL context current:
        init_gpu_module(bpy)  # a render makes Blender's current again (its exit needs one)
    assert reference.max() > 0.1 and (reference > 0).mean() > 0.9  # lit, World all around
    # Same shaders, data and view through two OpenGL pipelines. The viewport's output target
    # is half float (relative rounding ≤ 2⁻¹¹ ≈ 4.9e-4 of each pixel) and the two pipelines
    # differ in float32 rounding (the viewport recovers the camera position from its view
    # matrix): within 1e-3 of the peak (measured 5.2e-4, at the point light's highlight).
    error = np.abs(drawn - reference)
    assert error.max() < 1e-3 * reference.max(), error.max() / reference.max()

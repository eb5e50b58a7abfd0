"""The viewport's view_update/view_draw logic, driven with a stand-in engine and 3D-view matrices.

Background Blender has no 3D view, so the engine's display-space shader (colour management of
the final blit) cannot be bound: the stand-in engine skips that one call, everything else —
export, uploads, progressive accumulation, restarts, redraw requests — runs for real."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from blender_helpers import extension_submodule, init_gpu_module


def view_context(distance: float, width: int = 48, height: int = 32):
    import mathutils  # only importable once bpy is

    view = mathutils.Matrix.Translation((0.0, 0.0, -distance))
    proj = mathutils.Matrix(((1.5, 0, 0, 0), (0, 2.25, 0, 0), (0, 0, -1.002, -0.2), (0, 0, -1, 0)))
    region_data = SimpleNamespace(
        perspective_matrix=proj @ view, view_matrix=view, is_perspective=True
    )
    return SimpleNamespace(
        region=SimpleNamespace(width=width, height=height), region_data=region_data
    )


def stand_in_engine():
    engine = SimpleNamespace(redraws=0, reports=[])
    engine.bind_display_space_shader = lambda scene: None
    engine.unbind_display_space_shader = lambda: None
    engine.tag_redraw = lambda: setattr(engine, "redraws", engine.redraws + 1)
    engine.report = lambda kind, message: engine.reports.append(message)
    return engine


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
    assert engine.reports == [] and state.drawer.state.done == 5 and engine.redraws == 1
    viewport.view_draw(engine, context, depsgraph)
    viewport.view_draw(engine, context, depsgraph)  # 5 + 5 + 2: converged, no more redraws
    assert state.drawer.state.done == 12 and state.drawer.state.converged
    assert engine.redraws == 2
    image = np.array(state.output.texture_color.read(), dtype=np.float32)
    assert np.all(np.isfinite(image)) and image.max() > 0

    moved = view_context(4.0)  # the view changed: accumulation restarts, nothing re-exported
    drawer = state.drawer
    viewport.view_draw(engine, moved, depsgraph)
    assert state.drawer is drawer and state.drawer.state.done == 5

    settings.lights_per_redraw = 3  # a setting changed: restart with the new K
    viewport.view_draw(engine, moved, depsgraph)
    assert state.drawer.state.done == 3

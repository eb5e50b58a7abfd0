"""Which panels Blender shows under each engine, and what the BTF engine's panels list: the
data it honours (export/lights.py, export/world.py, the passes F12 writes), nothing else.
Panels are drawn into a recording layout (background Blender has no window to draw in) with
real Blender data. No renders: a few seconds."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from blender_helpers import RecordingLayout, draw_panel, extension_submodule, with_nodes

ENGINE = "BTF_RENDER"


def draw(panel, context) -> RecordingLayout:
    return draw_panel(panel, context)


def names(layout: RecordingLayout) -> set[str]:
    return {name for _data, name in layout.props}


def panels():
    return extension_submodule("btf_addon.blender.ui.blender_panels")


@pytest.mark.parametrize(
    ("light_type", "expected"),
    [
        ("POINT", {"type", "color", "energy", "shadow_soft_size"}),
        ("SPOT", {"type", "color", "energy", "shadow_soft_size", "spot_size", "spot_blend"}),
        ("SUN", {"type", "color", "energy"}),
        ("AREA", {"type", "color", "energy", "shape", "size", "size_y"}),
    ],
)
def test_light_panel_lists_what_the_engine_reads(bpy_module, fresh_scene, light_type, expected):
    bpy = bpy_module
    light = bpy.data.lights.new("L", light_type)
    if light_type == "AREA":
        light.shape = "RECTANGLE"
    context = SimpleNamespace(engine=ENGINE, light=light)
    panel = panels().BTF_LIGHT_PT_light
    assert panel.poll(context)
    assert not panel.poll(SimpleNamespace(engine="CYCLES", light=light))
    drawn = names(draw(panel, context)) - {"exposure"}  # Blender 4.x+ lights have exposure
    assert drawn == expected


def test_world_panel_shows_the_node_tree(bpy_module, fresh_scene):
    bpy = bpy_module
    world = with_nodes(bpy.data.worlds.new("W"))
    context = SimpleNamespace(engine=ENGINE, world=world)
    panel = panels().BTF_WORLD_PT_surface
    assert panel.poll(context) and not panel.poll(SimpleNamespace(engine="CYCLES", world=world))
    layout = draw(panel, context)
    (ntree, node, socket), *_ = layout.node_views
    assert ntree == world.node_tree and node.type == "OUTPUT_WORLD" and socket.name == "Surface"


def test_material_panels_by_engine(bpy_module, fresh_scene):
    """The BTF panel only under this engine; the surface panel for a material without BTF;
    Blender's slot list and preview gain this engine."""
    bpy = bpy_module
    material = with_nodes(bpy.data.materials.new("M"))
    btf_panel = extension_submodule("btf_addon.blender.ui.btf_panels").BTF_PT_material
    surface = panels().BTF_MATERIAL_PT_surface
    for engine in ("CYCLES", "BLENDER_EEVEE_NEXT", "BLENDER_EEVEE", "BLENDER_WORKBENCH"):
        context = SimpleNamespace(engine=engine, material=material)
        assert not btf_panel.poll(context) and not surface.poll(context)
    context = SimpleNamespace(engine=ENGINE, material=material)
    assert btf_panel.poll(context) and surface.poll(context)
    layout = draw(surface, context)
    assert layout.node_views and layout.node_views[0][2].name == "Surface"
    material.btf.enabled = True
    assert not surface.poll(context)  # a BTF material: its BTF panel says it all
    layout = draw(btf_panel, context)
    assert {"source", "exposure"} <= names(layout)
    assert layout.operators == ["btf.import_material"]
    for name in ("EEVEE_MATERIAL_PT_context_material", "MATERIAL_PT_preview"):
        assert ENGINE in getattr(bpy.types, name).COMPAT_ENGINES, name


def test_passes_panel_lists_the_passes_f12_writes(bpy_module, fresh_scene):
    bpy = bpy_module
    view_layer = bpy.context.view_layer
    context = SimpleNamespace(engine=ENGINE, view_layer=view_layer)
    panel = panels().BTF_VIEWLAYER_PT_passes
    assert panel.poll(context) and not panel.poll(SimpleNamespace(engine="CYCLES"))
    assert names(draw(panel, context)) == {
        "use_pass_combined",
        "use_pass_z",
        "use_pass_normal",
        "use_pass_uv",
    }
    # Blender's own passes panel (EEVEE's and Workbench's passes) and light panel stay theirs.
    for name in ("VIEWLAYER_PT_layer_passes", "DATA_PT_light", "DATA_PT_lightprobe"):
        assert ENGINE not in getattr(bpy.types, name).COMPAT_ENGINES, name


def test_render_panel_says_which_device_renders(bpy_module, fresh_scene):
    """Automatic: the first device that builds programs (GPU, system CPU driver, bundled
    PoCL), by its name and driver: the one the device report marks as F12's."""
    bpy = bpy_module
    ui = extension_submodule("btf_addon.blender.ui.btf_panels")
    devices = extension_submodule("btf_addon.cl.devices")
    used = [row for row in devices.device_report() if row["used"]]
    layout = draw(
        ui.BTF_PT_render_settings, SimpleNamespace(engine=ENGINE, scene=bpy.context.scene)
    )
    device = [t for t in layout.labels if t.startswith("F12 device:")]
    assert len(device) == 1, layout.labels
    if used:
        assert device[0] == f"F12 device: {used[0]['label']}", layout.labels
    else:
        assert "none builds" in device[0], layout.labels


def test_film_panel_has_transparent(bpy_module, fresh_scene):
    """Issue 32 item 1: F12 honours ``render.film_transparent`` and the guide says Film ›
    Transparent works, but no panel shown for this engine drew it."""
    bpy = bpy_module
    scene = bpy.context.scene
    film = extension_submodule("btf_addon.blender.ui.film").BTF_PT_film
    context = SimpleNamespace(engine=ENGINE, scene=scene)
    assert film.poll(context)
    assert (scene.render, "film_transparent") in draw(film, context).props


def test_material_panel_warns_while_its_source_is_missing(bpy_module, fresh_scene, tmp_path):
    """Issue 32 item 6: the panel showed nothing while its source was missing (only F12 or
    File › External Data › Report Missing said so)."""
    bpy = bpy_module
    material = bpy.data.materials.new("M")
    material.btf.enabled = True
    material.btf.source = str(tmp_path / "gone.btfm")
    btf_panel = extension_submodule("btf_addon.blender.ui.btf_panels").BTF_PT_material
    context = SimpleNamespace(engine=ENGINE, material=material)
    labels = draw(btf_panel, context).labels
    assert any("gone.btfm" in t and "no such file" in t for t in labels), labels
    (tmp_path / "gone.btfm").write_bytes(b"not a container")  # there, but cannot load
    errors = extension_submodule("btf_addon.core.errors")
    with pytest.raises(errors.BTFError):
        extension_submodule("btf_addon.blender.export.materials").load_cached(material.btf.source)
    labels = draw(btf_panel, context).labels
    assert any("gone.btfm" in t for t in labels), labels
    material.btf.enabled = False
    assert not [t for t in draw(btf_panel, context).labels if t]

"""Real-world size and mapping as a new user meets them: import onto a mesh with or without a
UV map, touch nothing, press F12, count the tiles."""

from __future__ import annotations

import math

import pytest
from blender_helpers import extension_submodule
from helpers import count_periods, shared_material, stripe_btf

from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.imageio import read_exr


def _plane_without_uvs(bpy, size: float):
    h = size / 2
    mesh = bpy.data.meshes.new("bare")
    mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    obj = bpy.data.objects.new("bare", mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _select_only(bpy, obj) -> None:
    for o in bpy.context.scene.objects:
        o.select_set(o == obj)
    bpy.context.view_layer.objects.active = obj


def test_import_chooses_mapping_by_the_mesh_and_asks_the_size(bpy_module, fresh_scene):
    bpy = bpy_module
    bpy.ops.mesh.primitive_cube_add(size=2.0)  # Blender's cube: unwrapped
    cube = bpy.context.object
    _select_only(bpy, cube)
    alu = shared_material("alu")
    assert bpy.ops.btf.import_material(filepath=str(alu), texel_size_mm=0.25) == {"FINISHED"}
    settings = cube.active_material.btf
    assert settings.mapping == "UV" and settings.use_real_world_size
    assert settings.texel_filter == "LINEAR"
    # BTFbase states no size: the import's answer (64 texels × 0.25 mm) is stored.
    assert tuple(settings.tile_size_mm) == pytest.approx((16.0, 16.0))

    bare = _plane_without_uvs(bpy, 1.0)
    _select_only(bpy, bare)
    assert bpy.ops.btf.import_material(filepath=str(alu)) == {"FINISHED"}
    settings = bare.active_material.btf
    assert settings.mapping == "BOX" and settings.box_space == "OBJECT"
    assert tuple(settings.tile_size_mm) == pytest.approx((6.4, 6.4))  # the 0.1 mm default
    # The Mapping panel hangs under the BTF material panel.
    panel = extension_submodule("btf_addon.blender.ui.mapping").BTF_PT_material_mapping
    assert panel.bl_parent_id == "BTF_PT_material"
    assert hasattr(bpy.types, "BTF_PT_material_mapping")


@pytest.mark.parametrize("unwrapped", [True, False])
def test_f12_shows_the_tiles_a_new_user_expects(bpy_module, fresh_scene, tmp_path, unwrapped):
    """A 0.5 m plane and a BTF whose file states a 25 mm tile, imported with every default:
    F12 shows 20 stripe periods across, through UV (unwrapped) or Box mapping (no UVs)."""
    bpy = bpy_module
    write_container(tmp_path / "stripes.btfm", stripe_btf(25.0))
    if unwrapped:
        bpy.ops.mesh.primitive_plane_add(size=0.5)  # UVs 0..1 across: 1 UV unit = 0.5 m
        obj = bpy.context.object
    else:
        obj = _plane_without_uvs(bpy, 0.5)
    _select_only(bpy, obj)
    bpy.ops.btf.import_material(filepath=str(tmp_path / "stripes.btfm"))
    assert obj.active_material.btf.mapping == ("UV" if unwrapped else "BOX")
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 0.5
    cam.location = (0.0, 0.0, 2.0)
    cam.rotation_euler = (0.0, 0.0, 0.0)  # looking down −Z, +X to the right
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.engine = "BTF_RENDER"
    scene.render.resolution_x, scene.render.resolution_y = 256, 8
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "f12.exr")
    scene.btf_render.lighting = "HEADLIGHT"
    bpy.ops.render.render(write_still=True)
    image = read_exr(tmp_path / "f12.exr")
    assert count_periods(image[4, :, 0]) == 20
    assert math.isclose(scene.unit_settings.scale_length, 1.0)


class _Layout:
    """Records what a panel draws (background Blender has no UI to draw into)."""

    def __init__(self):
        self.props, self.labels = [], []
        self.use_property_split = self.active = None

    def prop(self, _data, name, **_kw):
        self.props.append(name)

    def label(self, text="", **_kw):
        self.labels.append(text)

    def column(self, **_kw):
        return self


def test_mapping_panel_states_the_tile_on_the_active_object(bpy_module, fresh_scene):
    from types import SimpleNamespace

    bpy = bpy_module
    bpy.ops.mesh.primitive_cube_add(size=2.0)
    cube = bpy.context.object
    _select_only(bpy, cube)
    bpy.ops.btf.import_material(filepath=str(shared_material("alu")), texel_size_mm=0.25)
    module = extension_submodule("btf_addon.blender.ui.mapping")
    # Blender's cube: 24 m² of faces on 6 UV squares of 1/4 → 8 m per UV unit.
    assert module.mesh_units_per_uv(cube) == pytest.approx(8.0, rel=1e-6)
    panel = module.BTF_PT_material_mapping
    layout = _Layout()
    stub = SimpleNamespace(layout=layout)
    stub._draw_here = lambda *args: panel._draw_here(stub, *args)
    context = SimpleNamespace(material=cube.active_material, object=cube, scene=bpy.context.scene)
    panel.draw(stub, context)
    assert {"mapping", "texel_filter", "use_real_world_size", "tile_size_mm"} <= set(layout.props)
    # Issue 32 item 5: BTFbase states no size; the panel says the number is Import's guess.
    assert "Tile 16 × 16 mm (assumed on import: 0.25 mm per texel)" in layout.labels
    assert any(t.startswith("The source states no size") for t in layout.labels)
    assert "1 tile ≈ 16 mm on Cube" in layout.labels
    cube.active_material.btf.tile_size_mm = (20.0, 20.0)  # measured: the user's number now
    layout.labels.clear()
    panel.draw(stub, context)
    assert "Tile 20 × 20 mm (set by you)" in layout.labels
    assert not any(t.startswith("The source states no size") for t in layout.labels)
    cube.active_material.btf.tile_size_mm = (16.0, 16.0)
    cube.active_material.btf.uv_scale = 2.0  # twice the repeats: half the tile
    layout.labels.clear()
    panel.draw(stub, context)
    assert "1 tile ≈ 8 mm on Cube" in layout.labels


def test_mapping_panel_does_not_reload_a_broken_source_on_every_redraw(
    bpy_module, fresh_scene, tmp_path, monkeypatch
):
    """The panel redraws on every mouse move: a source that fails to load is tried once per
    version of the file, and a rewritten file is tried again."""
    import os

    bpy = bpy_module
    broken = tmp_path / "broken.btfm"
    broken.write_bytes(b"not a container")
    material = bpy.data.materials.new("broken")
    material.btf.source = str(broken)
    module = extension_submodule("btf_addon.blender.ui.mapping")
    materials = extension_submodule("btf_addon.blender.export.materials")
    calls = []
    real = materials.load_btf
    monkeypatch.setattr(
        materials, "load_btf", lambda path, **kw: calls.append(path) or real(path, **kw)
    )
    first = module.stated_size(material.btf)
    again = module.stated_size(material.btf)
    assert first[0] is None and "source not readable" in first[1], first
    assert again == first and len(calls) == 1, calls
    # A rewritten file (new mtime) is read again: the user fixed it.
    write_container(broken, stripe_btf(10.0))
    stamp = broken.stat().st_mtime + 5.0
    os.utime(broken, (stamp, stamp))
    size, origin = module.stated_size(material.btf)
    assert len(calls) == 2 and size is not None, (size, origin)

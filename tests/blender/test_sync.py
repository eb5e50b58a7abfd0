"""blender/sync.py is the one place that turns Blender's data into plain values: every entry
point gets the same frame size (Blender's integer rule) and the same render settings (with the
scene's film filter).

The bugs it fixed: the accuracy report, ``render``'s size and the bridge's export sized frames
with a float product (100 px at 29 %: 28 instead of Blender's 29), and the XTAL bridge (its
operator and its CLI) read ``scene.btf_render`` without the film filter that F12 and
Blender's VR session honour."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from blender_helpers import extension_submodule, sphere_on_ground
from helpers import ROOT

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container

#: (resolution, percentage) pairs where the float rule ``int(res * pct / 100)`` is a pixel
#: short of Blender's ``res * pct // 100``.
DISAGREEING = [
    (r, p) for r in range(1, 4000) for p in range(1, 101) if int(r * (p / 100)) != r * p // 100
]


def test_the_float_rule_was_wrong_for_these_sizes():
    assert (100, 29) in DISAGREEING and len(DISAGREEING) > 100


def test_frame_size_is_blenders_own(bpy_module, fresh_scene, tmp_path):
    """Blender sizes the render result itself: F12 at 100 px × 29 % makes a 29-pixel image
    (our result must match its buffer, final_render.check_result_size), and sync says 29."""
    bpy = bpy_module
    sync = extension_submodule("btf_addon.blender.sync")
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (100, 100), 8, 4)
    scene.render.resolution_percentage = 29
    scene.btf_render.final_mode = "VIRTUAL"
    scene.btf_render.lights_total = 4
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(tmp_path / "f12.exr"))
    assert tuple(image.size) == sync.frame_size(scene.render) == (29, 29)
    for r, p in DISAGREEING[:: max(1, len(DISAGREEING) // 50)]:
        scene.render.resolution_x, scene.render.resolution_y = r, 7
        scene.render.resolution_percentage = p
        assert sync.frame_size(scene.render) == (r * p // 100, max(1, 7 * p // 100))


def test_the_accuracy_report_predicts_for_blenders_frame_size(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    accuracy_run = extension_submodule("btf_addon.blender.accuracy.run")
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (100, 100), 8, 4)
    scene.render.resolution_percentage = 29
    estimate, _rungs, _renderer = accuracy_run.prepare(
        bpy.context.evaluated_depsgraph_get(), longest=12, setup=False
    )
    assert estimate.full_size == (29, 29)


def test_the_bridge_gets_the_scenes_film_filter(bpy_module, fresh_scene, tmp_path):
    """The XTAL bridge's operator hands its bridge the same settings as F12: the film filter
    of scene.cycles included (it used to get Blackman-Harris 1.5 px whatever the scene said)."""
    bpy = bpy_module
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (32, 32), 8, 4)
    scene.cycles.pixel_filter_type = "GAUSSIAN"
    scene.cycles.filter_width = 2.5
    module = extension_submodule("btf_addon.blender.vr.xtal_bridge")
    sync = extension_submodule("btf_addon.blender.sync")
    made = []

    class StandIn:
        def __init__(self, exported, render_settings, settings):
            self.render_settings, self.settings = render_settings, settings
            made.append(self)

        def start(self):
            pass

        def run_frame(self):
            return False

        def close(self):
            pass

        def pop_edits(self):
            return []

    controller = module.BridgeController(scene, bpy.context.view_layer, make_bridge=StandIn)
    controller.start()
    try:
        controller.thread.join(10.0)
    finally:
        controller.stop()
    (bridge,) = made
    assert bridge.render_settings == sync.render_settings(scene)
    assert (bridge.render_settings.pixel_filter, bridge.render_settings.filter_width) == (
        "GAUSSIAN",
        2.5,
    )
    final_render = extension_submodule("btf_addon.blender.final_render")
    assert final_render.render_settings is sync.render_settings  # F12 reads the same


#: Modules allowed to read Blender's frame size or the render properties themselves.
SYNC = "btf_addon/blender/sync.py"


def _reads(path: Path) -> list[str]:
    """What a module reads that only sync may: ``resolution_percentage`` (read, not set) and
    ``RenderSettings.from_scene``/``from_properties`` applied to a scene's ``btf_render``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Attribute) and node.attr == "resolution_percentage":
            if isinstance(node.ctx, ast.Load):
                found.append(f"{path.name}:{node.lineno} resolution_percentage")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            name = node.func.attr
            if name == "from_scene" or (
                name == "from_properties"
                and node.args
                and isinstance(node.args[0], ast.Attribute)
                and node.args[0].attr == "btf_render"
            ):
                found.append(f"{path.name}:{node.lineno} {name}")
    return found


@pytest.mark.parametrize("package", ["blender", "cli"])
def test_every_entry_point_reads_blender_through_sync(package):
    """F12, the viewport, the VR session, the bridge operator and CLI, stereo captures, the
    accuracy report and ``render``: none computes the size or reads the settings itself."""
    offenders = []
    for path in sorted((ROOT / "btf_addon" / package).rglob("*.py")):
        if path.relative_to(ROOT).as_posix() != SYNC:
            offenders += _reads(path)
    assert offenders == []


def test_one_meaning_per_enum_number_and_one_default(bpy_module, installed):
    """The material's mapping and texel filter: Blender's EnumProperty numbers are the packed
    block's numbers (core/codecs/packed.py), and the plain-array defaults are the properties'."""
    packed = extension_submodule("btf_addon.core.codecs.packed")
    mapping = extension_submodule("btf_addon.core.mapping")
    scene = extension_submodule("btf_addon.scene.scene")
    props = bpy_module.types.Material.bl_rna.properties["btf"].fixed_type.properties
    for name, ids in (("texel_filter", packed.FILTER_IDS), ("mapping", packed.MAPPING_IDS)):
        items = {item.identifier: item.value for item in props[name].enum_items}
        assert items == ids, name
    assert mapping.Placement().texel_filter == props["texel_filter"].default
    assert mapping.Placement().mapping == props["mapping"].default
    field = scene.Material.__dataclass_fields__["texel_filter"]
    assert field.default == props["texel_filter"].default

"""What differs between the supported Blenders (4.2 LTS, 4.5 LTS, 5.0 on Python 3.11; 5.1+ on
Python 3.13), checked on whichever one runs: `make test BLENDER=X.Y` runs this file on each.

The zip bundles every compiled package once per Python; Blender must have extracted the ones for
its own Python, and the extension must draw a BTF material in the viewport with them."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from blender_helpers import (
    extension_submodule,
    init_gpu_module,
    stand_in_engine,
    view_context,
    with_nodes,
)
from helpers import shared_material

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.formats.container import write_container

# The compiled packages the manifest bundles, by an extension module each one installs.
COMPILED = {
    "pyopencl": "pyopencl/_cl",
    "moderngl": "moderngl/mgl",
    "glcontext": "glcontext/egl",
    "openexr": "OpenEXR",
    "hidapi": "hid",
    "siphash24": "siphash24",
}


def extension_site_packages(bpy) -> Path:
    """Where Blender extracts extension wheels: ``<EXTENSIONS>/.local/lib/python3.X/site-packages``
    (one folder per Python, so Blenders of different Pythons never share it)."""
    local = Path(bpy.utils.user_resource("EXTENSIONS", path=".local"))
    return local / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"


def test_compat_reports_the_running_blender(bpy_module, installed):
    compat = extension_submodule("btf_addon.blender.compat")
    assert compat.VERSION == tuple(bpy_module.app.version)
    assert compat.at_least(4, 2) and not compat.at_least(99, 0)


def test_blender_extracted_the_wheels_for_its_own_python(bpy_module, installed):
    """Each compiled package is bundled as cp311 and cp313 wheels; Blender installs only its own
    Python's (4.2.0 did not filter by Python: hence blender_version_min 4.2.13)."""
    site = extension_site_packages(bpy_module)
    tag = f"cpython-{sys.version_info[0]}{sys.version_info[1]}"
    binaries = sorted(site.rglob("*.cpython-*.so"))
    assert binaries, f"no compiled modules extracted into {site}"
    wrong = [p.relative_to(site) for p in binaries if tag not in p.name]
    assert not wrong, f"wheels for another Python were installed: {wrong}"
    for package, module in COMPILED.items():
        found = list(site.glob(f"{module}.{tag}-*.so"))
        assert found, f"{package}: no {module}.{tag}-*.so in {site}"


def test_new_materials_and_worlds_get_node_trees(bpy_module, fresh_scene):
    """4.2 and 4.5 create node-less materials and worlds; compat.with_nodes evens that out."""
    compat = extension_submodule("btf_addon.blender.compat")
    material = compat.with_nodes(bpy_module.data.materials.new("m"))
    world = compat.with_nodes(bpy_module.data.worlds.new("w"))
    assert material.node_tree.nodes.get("Principled BSDF") is not None
    assert world.node_tree.nodes.get("Background") is not None


def _draw_viewport(bpy, source) -> np.ndarray:
    """The viewport image (h, w, 4) of a unit sphere 5 units in front of the view with a BTF
    material from ``source`` (None: BTF off), under a uniform white World."""
    viewport = extension_submodule("btf_addon.blender.viewport")
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=32, ring_count=16)
    material = bpy.data.materials.new("BTF")
    if source is not None:
        material.btf.enabled = True
        material.btf.source = str(source)
    bpy.context.object.data.materials.append(material)
    world = with_nodes(bpy.data.worlds.new("White"))
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bpy.context.scene.world = world
    settings = bpy.context.scene.btf_render
    settings.lights_total = settings.lights_per_redraw = 16
    engine, context = stand_in_engine(), view_context(5.0)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    viewport.view_update(engine, context, depsgraph)
    viewport.view_draw(engine, context, depsgraph)
    assert engine.reports == [], engine.reports
    state = engine.btf_viewport
    assert state.view.state.converged
    image = state.view.read()  # the resolved output as float32, bottom row first
    assert image.shape == (32, 48, 4)
    return image


@pytest.mark.parametrize("kind", ["synthetic", "measured"])
def test_viewport_draws_a_btf_material(bpy_module, fresh_scene, tmp_path, kind):
    """The BTF shows in the viewport: an orange GGX BTF turns the sphere orange where the
    plain material (grey 0.8) is grey; the measured alu BTF differs from the plain material."""
    init_gpu_module(bpy_module)
    if kind == "synthetic":
        source = tmp_path / "ggx.btfm"
        write_container(source, GGXBTF((0.9, 0.6, 0.3), 0.4))
    else:
        source = shared_material("alu")
    btf = _draw_viewport(bpy_module, source)
    bpy_module.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    plain = _draw_viewport(bpy_module, None)
    assert np.all(np.isfinite(btf))
    # The sphere is where the image is not the white World (about 60 of 1536 pixels).
    sphere = np.any(np.abs(plain[..., :3] - 1.0) > 1e-3, axis=-1)
    assert 30 < sphere.sum() < 200, sphere.sum()
    mean_btf, mean_plain = btf[sphere, :3].mean(axis=0), plain[sphere, :3].mean(axis=0)
    assert mean_btf.max() > 0.05, mean_btf
    if kind == "synthetic":
        # 16 virtual lights leave each pixel noisy, so whole-sphere means are compared. The
        # BTF's albedo ratio red/blue is 3, the plain material's (grey 0.8) is 1: 1.5 leaves
        # room for the GGX lobe's white highlight without accepting a grey sphere.
        assert mean_btf[0] > 1.5 * mean_btf[2], mean_btf
        assert abs(mean_plain[0] - mean_plain[2]) < 0.05 * mean_plain.max(), mean_plain
    else:
        # Any real difference: the measured BTF's colour and reflectance are not grey 0.8's.
        assert np.abs(mean_btf - mean_plain).max() > 0.02, (mean_btf, mean_plain)

"""Build BTF Material Library as a user runs it (bpy.ops), and its assets applied as the Asset
Browser applies them (append, link) from a library folder moved elsewhere.

One build serves the file: a sources folder with a red Lambertian .btfm, a corrupt .btfm and,
where the shared research data is present, the BTFbase ``alu`` folder; the GGX preset; 48 × 48
previews from 16 virtual lights (the file: about 20 s here, the extension's build included).
Last, Blender's own material preview job through this engine: an expected failure until
blender/export/camera.py reads the evaluated camera."""

from __future__ import annotations

import math
import shutil
import threading
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from blender_helpers import extension_submodule, with_nodes
from helpers import SHARED_BTFBASE, shared_material

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.imageio import read_exr

PREVIEW = 48
LIBRARY_BLEND = "btf_materials.blend"
DATA_KINDS = ("materials", "scenes", "objects", "meshes", "cameras", "worlds", "images", "lights")


def _names(bpy) -> dict[str, set[str]]:
    return {kind: set(getattr(bpy.data, kind).keys()) for kind in DATA_KINDS}


def _empty_file(bpy) -> None:
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)


@pytest.fixture(scope="module")
def built(bpy_module, installed, tmp_path_factory):
    """The library built once from ``root/sources`` into ``root/library``; what the open file
    held before and after the build."""
    bpy = bpy_module
    root = tmp_path_factory.mktemp("btf-library")
    sources = root / "sources"
    sources.mkdir()
    write_container(sources / "red.btfm", LambertianBTF((0.8, 0.1, 0.1)))
    (sources / "broken.btfm").write_bytes(b"not a BTF container")
    expected = {"red", "GGX"}
    alu = SHARED_BTFBASE / "alu"
    if (alu / "all_materialInfo.txt").is_file():
        shutil.copytree(alu, sources / "alu")
        expected.add("alu")
    _empty_file(bpy)
    bpy.ops.mesh.primitive_cube_add()  # the user's own data, which must stay as it is
    before = _names(bpy)
    result = bpy.ops.btf.build_asset_library(
        directory=str(root / "library"),
        source_folder=str(sources),
        presets={"GGX"},
        preview_size=PREVIEW,
        preview_lights=16,
    )
    assert result == {"FINISHED"}
    return {"root": root, "expected": expected, "before": before, "after": _names(bpy)}


@pytest.fixture(scope="module")
def moved(built, tmp_path_factory) -> Path:
    """The library folder and its sources copied elsewhere as a whole. The tests check that
    sources resolve inside the copy: a path still relative to the original would not."""
    target = tmp_path_factory.mktemp("moved") / "btf-library"
    shutil.copytree(built["root"], target)
    return target


def _needs_import_handlers(bpy) -> None:
    """Applying an asset rebases its source in ``blend_import_post``, which Blender has from
    4.3 on (the guide says so); on 4.2 an applied asset keeps its library-relative path."""
    if not hasattr(bpy.app.handlers, "blend_import_post"):
        pytest.skip(
            f"Blender {bpy.app.version_string} has no blend_import_post handler (4.3+): applied "
            "assets keep the library's relative source there (docs/user-guide.md says 4.3+)"
        )


def _linked_assets(bpy, blend: Path):
    with bpy.data.libraries.load(str(blend), link=True, assets_only=True) as (source, target):
        target.materials = list(source.materials)
    return {m.name: m for m in target.materials}


def _catalog_ids(file: Path) -> dict[str, str]:
    """id → path of a blender_assets.cats.txt."""
    lines = [line for line in file.read_text().splitlines() if line and line[0] != "#"]
    assert lines[0] == "VERSION 1"
    return {line.split(":")[0]: line.split(":")[1] for line in lines[1:]}


def test_one_asset_per_source_with_an_engine_preview_and_a_catalog(bpy_module, built):
    bpy = bpy_module
    library = built["root"] / "library"
    catalogs = _catalog_ids(library / "blender_assets.cats.txt")
    _empty_file(bpy)
    assets = _linked_assets(bpy, library / LIBRARY_BLEND)
    assert set(assets) == built["expected"]  # the corrupt source left out, the rest built
    want_catalog = {"red": "BTF/BTF Files", "GGX": "BTF/Synthetic", "alu": "BTF/BTFbase"}
    for name, material in assets.items():
        assert material.btf.enabled and material.btf.mapping == "BOX"
        data = material.asset_data
        assert catalogs[data.catalog_id] == want_catalog[name], name
        assert data.description.startswith(name) and "BTF" in data.tags
        assert tuple(material.preview.image_size) == (PREVIEW, PREVIEW), name
        pixels = np.array(material.preview.image_pixels_float[:]).reshape(PREVIEW, PREVIEW, 4)
        swatch = pixels[..., 3] > 0.99
        assert 0.2 < swatch.mean() < 0.9, name  # the swatch over a transparent film
        assert pixels[..., :3][swatch].std(axis=0).max() > 0.02, name  # shaded, not flat
    red = np.array(assets["red"].preview.image_pixels_float[:]).reshape(-1, 4)
    red = red[red[:, 3] > 0.99, :3].mean(axis=0)
    assert red[0] > 2 * red[1] and red[0] > 2 * red[2]  # the source's own colour
    assert (library / "synthetic" / "ggx.btfm").is_file()  # the preset's file, in the library


def test_building_leaves_the_open_file_as_it_was(built):
    assert built["after"] == built["before"]


def test_a_source_that_fails_is_reported(bpy_module, fresh_scene, tmp_path):
    """Each failing source is named; with nothing built, nothing is written."""
    (tmp_path / "sources").mkdir()
    (tmp_path / "sources" / "broken.btfm").write_bytes(b"not a BTF container")
    with pytest.raises(RuntimeError, match=r"no asset could be built: .*broken\.btfm: not a BTF"):
        bpy_module.ops.btf.build_asset_library(
            directory=str(tmp_path / "library"),
            source_folder=str(tmp_path / "sources"),
            presets=set(),
        )
    assert not (tmp_path / "library" / LIBRARY_BLEND).exists()


def _render_on_sphere(bpy, material, out: Path) -> np.ndarray:
    """A tiny F12 of ``material`` on a sphere filling the middle of the frame, lit by a sun."""
    scene = bpy.context.scene
    scene.render.engine = "BTF_RENDER"
    scene.render.resolution_x, scene.render.resolution_y = 24, 16
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.btf_render.final_mode = "VIRTUAL"
    scene.btf_render.lights_total = 8
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=16, ring_count=8)
    bpy.context.object.data.materials.append(material)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(30), 0.0, 0.0)  # from the camera's side
    scene.collection.objects.link(sun)
    camera = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    camera.location, camera.rotation_euler = (0.0, -5.0, 0.0), (math.radians(90), 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.world = with_nodes(bpy.data.worlds.new("W"))
    scene.render.filepath = str(out)
    bpy.ops.render.render(write_still=True)
    return read_exr(out)


@pytest.mark.parametrize("method", ["append", "link"])
def test_an_applied_asset_renders_from_the_moved_library(bpy_module, moved, tmp_path, method):
    """The Asset Browser's Append (Reuse Data) and Link, done by wm.append / wm.link into an
    unsaved file: the source resolves inside the moved folder and F12 renders it red."""
    _needs_import_handlers(bpy_module)
    bpy = bpy_module
    _empty_file(bpy)
    blend = moved / "library" / LIBRARY_BLEND
    getattr(bpy.ops.wm, method)(directory=f"{blend}/Material/", filename="red")
    material = bpy.data.materials["red"]
    assert (material.library is not None) == (method == "link")
    resolved = Path(bpy.path.abspath(material.btf.source)).resolve()
    assert resolved == moved / "sources" / "red.btfm", material.btf.source
    rgb = _render_on_sphere(bpy, material, tmp_path / "f12.exr")[6:10, 10:14]
    assert rgb[..., 0].min() > 0.05 and (rgb[..., 0] > 2 * rgb[..., 1]).all()


def test_an_appended_source_is_relative_in_a_saved_file(bpy_module, moved, tmp_path):
    """Appended into a saved file, the source is relative to that file (farm-safe), and every
    kind of asset resolves inside the moved library folder."""
    _needs_import_handlers(bpy_module)
    bpy = bpy_module
    _empty_file(bpy)
    (tmp_path / "shot").mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot" / "shot.blend"))
    blend = moved / "library" / LIBRARY_BLEND
    with bpy.data.libraries.load(str(blend), link=False) as (source, target):
        target.materials = list(source.materials)
    paths = extension_submodule("btf_addon.blender.paths")
    for material in target.materials:
        assert material.btf.source.startswith("//"), material.name
        resolved = Path(bpy.path.abspath(material.btf.source)).resolve()
        assert resolved.is_relative_to(moved) and resolved.exists(), material.btf.source
        assert paths.source_problem(material.btf.source) == "", material.name


def test_a_material_appended_with_an_object_is_rebased_too(bpy_module, fresh_scene, tmp_path):
    """Not only assets: a BTF material that comes along with an appended object (another
    shot's file) keeps pointing at its data."""
    _needs_import_handlers(bpy_module)
    bpy = bpy_module
    write_container(tmp_path / "data" / "grey.btfm", LambertianBTF(0.5))
    bpy.ops.mesh.primitive_cube_add()
    material = bpy.data.materials.new("Grey")
    material.btf.enabled = True
    material.btf.source = "//../data/grey.btfm"  # relative to the file written below
    bpy.context.object.data.materials.append(material)
    (tmp_path / "other").mkdir()
    bpy.data.libraries.write(str(tmp_path / "other" / "other.blend"), {bpy.context.object})
    _empty_file(bpy)
    bpy.ops.wm.append(directory=f"{tmp_path / 'other' / 'other.blend'}/Object/", filename="Cube")
    source = bpy.data.materials["Grey"].btf.source
    assert Path(source) == tmp_path / "data" / "grey.btfm"  # absolute: this file is unsaved


def test_copied_sources_make_the_library_folder_self_contained(bpy_module, fresh_scene, tmp_path):
    _needs_import_handlers(bpy_module)
    bpy = bpy_module
    write_container(tmp_path / "sources" / "grey.btfm", LambertianBTF(0.5))
    result = bpy.ops.btf.build_asset_library(
        directory=str(tmp_path / "library"),
        source_folder=str(tmp_path / "sources"),
        presets=set(),
        copy_sources=True,
        preview_size=16,
        preview_lights=4,
    )
    assert result == {"FINISHED"}
    shutil.rmtree(tmp_path / "sources")
    moved = tmp_path / "elsewhere" / "library"
    shutil.move(tmp_path / "library", moved)
    _empty_file(bpy)
    bpy.ops.wm.append(directory=f"{moved / LIBRARY_BLEND}/Material/", filename="grey")
    source = Path(bpy.data.materials["grey"].btf.source)
    assert source == moved / "sources" / "grey.btfm" and source.is_file()


def test_catalogs_already_in_the_folder_are_kept(bpy_module, installed, tmp_path):
    library = extension_submodule("btf_addon.blender.tools.asset_library")
    mine = "0b5e4c1a-8f0e-4d47-a3a5-0c7b1d2e3f40"
    (tmp_path / library.CATALOG_FILE).write_text(
        f"VERSION 1\n\n{mine}:BTF/BTFbase:mine\n1d2c3b4a-0000-4000-8000-000000000001:Props:Props\n"
    )
    ids = library.write_catalogs(tmp_path, ["BTF/BTFbase", "BTF/Synthetic"])
    assert ids["BTF/BTFbase"] == mine  # an existing catalog keeps its id
    catalogs = _catalog_ids(tmp_path / library.CATALOG_FILE)
    assert catalogs == {
        mine: "BTF/BTFbase",
        "1d2c3b4a-0000-4000-8000-000000000001": "Props",
        ids["BTF/Synthetic"]: "BTF/Synthetic",
        library.catalog_uuid("BTF"): "BTF",
    }
    assert library.write_catalogs(tmp_path, ["BTF/Synthetic"]) == {
        "BTF/Synthetic": ids["BTF/Synthetic"]  # the same id on a rebuild
    }


def test_the_library_is_added_to_the_preferences_when_asked(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    libraries = bpy.context.preferences.filepaths.asset_libraries
    result = bpy.ops.btf.build_asset_library(
        directory=str(tmp_path / "presets"),
        presets={"LAMBERTIAN"},
        preview_size=16,
        preview_lights=4,
        register_library=True,
        library_name="BTF Test Library",
    )
    assert result == {"FINISHED"}
    library = libraries.get("BTF Test Library")
    try:
        assert library is not None
        assert Path(bpy.path.abspath(library.path)).resolve() == (tmp_path / "presets").resolve()
        assert library.import_method.startswith("APPEND")
    finally:
        if library is not None:
            libraries.remove(library)


def test_render_preview_stores_the_engines_image(bpy_module, fresh_scene, tmp_path):
    """The material's preview rendered by this engine and stored with ID.preview_ensure()."""
    bpy = bpy_module
    write_container(tmp_path / "red.btfm", LambertianBTF((0.8, 0.1, 0.1)))
    material = with_nodes(bpy.data.materials.new("Red"))
    material.btf.enabled = True
    material.btf.source = str(tmp_path / "red.btfm")
    panel = extension_submodule("btf_addon.blender.tools.asset_library")
    panel = panel.BTF_PT_material_asset_preview  # Material Properties › BTF › Asset Preview
    assert panel.poll(SimpleNamespace(engine="BTF_RENDER", material=material))
    assert not panel.poll(SimpleNamespace(engine="CYCLES", material=material))
    before = _names(bpy)
    assert bpy.ops.btf.render_preview(material="Red", size=32) == {"FINISHED"}
    assert _names(bpy) == before  # its stage removed again
    assert tuple(material.preview.image_size) == (32, 32)
    pixels = np.array(material.preview.image_pixels_float[:]).reshape(32, 32, 4)
    assert pixels[16, 16, 3] == 1.0 and pixels[0, 0, 3] == 0.0  # swatch, transparent corner
    assert pixels[16, 16, 0] > 2 * pixels[16, 16, 1]


def test_a_btfbase_asset_keeps_the_folder(bpy_module, moved):
    _needs_import_handlers(bpy_module)
    shared_material("alu")  # skips, saying why, without the research data
    bpy = bpy_module
    _empty_file(bpy)
    assets = _linked_assets(bpy, moved / "library" / LIBRARY_BLEND)
    resolved = Path(bpy.path.abspath(assets["alu"].btf.source)).resolve()
    assert resolved == moved / "sources" / "alu"
    assert "mlvq" in assets["alu"].asset_data.tags


def test_blenders_own_material_preview_renders_through_the_engine(
    bpy_module, fresh_scene, tmp_path, monkeypatch
):
    """Blender's preview job (what the Material Properties' Preview panel runs) calls this
    engine (bl_use_preview) headless; in background Blender its image never reaches the ID
    (the job's end runs from the event loop), so the engine's Combined pass is looked at."""
    bpy = bpy_module
    final_render = extension_submodule("btf_addon.blender.final_render")
    write_container(tmp_path / "red.btfm", LambertianBTF((0.8, 0.1, 0.1)))
    bpy.context.scene.render.engine = "BTF_RENDER"
    material = with_nodes(bpy.data.materials.new("Red"))
    material.btf.enabled = True
    material.btf.source = str(tmp_path / "red.btfm")
    seen: dict = {}
    finished = threading.Event()
    render, set_passes = final_render.render, final_render.set_passes

    def watched_render(engine, depsgraph):
        seen["is_preview"] = engine.is_preview
        try:
            render(engine, depsgraph)
        finally:
            finished.set()

    def watched_set_passes(layer, region, images):
        seen["combined"] = np.array(images["Combined"])
        set_passes(layer, region, images)

    monkeypatch.setattr(final_render, "render", watched_render)
    monkeypatch.setattr(final_render, "set_passes", watched_set_passes)
    material.preview_ensure()
    with bpy.context.temp_override(id=material):
        if not bpy.ops.ed.lib_id_generate_preview.poll():
            pytest.skip(
                f"Blender {bpy.app.version_string}'s Generate Preview operator refuses a "
                "windowless context (5.3 asks for more than an ID); 4.2 to 5.0 run it"
            )
        assert bpy.ops.ed.lib_id_generate_preview() == {"FINISHED"}
    assert finished.wait(120), "Blender's preview job never called the engine"
    assert seen["is_preview"]
    combined = seen["combined"]
    assert combined[..., 3].max() > 0.0 and combined[..., 0].max() > 0.05

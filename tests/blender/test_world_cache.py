"""The World image's pixels on disk between sessions (blender/export/world_cache.py): a second
read of the same file with the same settings comes from the disk, equal to Blender's own read;
a changed file or colour space is read from Blender again; an image edited in Blender, packed
or generated never touches the disk."""

from __future__ import annotations

import os

import numpy as np
import pytest
from blender_helpers import extension_submodule, with_nodes

from btf_addon.core.formats.imageio import write_exr


@pytest.fixture
def store(tmp_path, monkeypatch, installed):
    cache = extension_submodule("btf_addon.blender.export.world_cache")
    before = cache.STORE.folder()
    cache.STORE.set_folder(tmp_path / "world")
    monkeypatch.setattr(cache.STORE, "stats", dict.fromkeys(cache.STORE.stats, 0))
    yield cache.STORE
    cache.STORE.set_folder(before)


def world():
    return extension_submodule("btf_addon.blender.export.world")


def sky(path, seed: int):
    write_exr(path, np.random.default_rng(seed).gamma(0.6, 1.0, (8, 16, 3)).astype(np.float32))
    return path


def test_a_second_read_comes_from_the_disk(bpy_module, fresh_scene, store, tmp_path):
    path = sky(tmp_path / "sky.exr", 1)
    first = world().image_pixels(bpy_module.data.images.load(str(path)))
    assert store.stats["stored"] == 1 and store.stats["disk_hits"] == 0
    other = bpy_module.data.images.load(str(path), check_existing=False)  # as a new session
    second = world().image_pixels(other)
    assert store.stats["disk_hits"] == 1
    np.testing.assert_array_equal(second, first)
    np.testing.assert_array_equal(second, world()._read_pixels(other))  # Blender's own read


def test_a_changed_file_or_colour_space_is_read_again(bpy_module, fresh_scene, store, tmp_path):
    path = sky(tmp_path / "sky.exr", 1)
    image = bpy_module.data.images.load(str(path))
    first = world().image_pixels(image)
    sky(path, 2)  # the file saved again from a paint program
    stat = os.stat(path)
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000))  # coarse clocks
    image.reload()
    changed = world().image_pixels(image)
    assert store.stats["disk_hits"] == 0 and store.stats["stored"] == 2
    assert not np.array_equal(changed, first)
    np.testing.assert_array_equal(changed, world()._read_pixels(image))
    image.colorspace_settings.name = "Non-Color"
    world().image_pixels(image)
    assert store.stats["disk_hits"] == 0 and store.stats["stored"] == 3


def test_edited_packed_or_generated_images_are_read_from_blender(
    bpy_module, fresh_scene, store, tmp_path
):
    image = bpy_module.data.images.load(str(sky(tmp_path / "sky.exr", 1)))
    world().image_pixels(image)
    pixels = np.empty(len(image.pixels), dtype=np.float32)
    image.pixels.foreach_get(pixels)
    pixels[0] = 7.0  # bottom-left red, edited in Blender and not saved
    image.pixels.foreach_set(pixels)
    assert image.is_dirty
    assert world().image_pixels(image)[-1, 0, 0] == 7.0  # row 0 at the top
    assert store.stats["disk_hits"] == 0 and store.stats["stored"] == 1
    image.pack()
    world().image_pixels(image)
    generated = bpy_module.data.images.new("G", 4, 4, float_buffer=True)
    world().image_pixels(generated)
    assert store.stats["disk_hits"] == 0 and store.stats["stored"] == 1


def sky_world(bpy, path, strength: float, name: str = "W"):
    """A World lit by the image at ``path`` (Background ← Environment Texture)."""
    world = with_nodes(bpy.data.worlds.new(name))
    nodes = world.node_tree.nodes
    nodes["Background"].inputs["Strength"].default_value = strength
    texture = nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(str(path), check_existing=False)  # as a new session
    world.node_tree.links.new(texture.outputs["Color"], nodes["Background"].inputs["Color"])
    return world


def sunny_sky(path, seed: int):
    pixels = np.random.default_rng(seed).gamma(0.6, 1.0, (32, 64, 3)).astype(np.float32)
    pixels[5:7, 20:22] = 400.0  # a sun beside a patchy sky: the state holds its tables too
    write_exr(path, pixels)
    return path


def test_the_built_environment_comes_back_from_the_disk(bpy_module, fresh_scene, store, tmp_path):
    path = sunny_sky(tmp_path / "sky.exr", 1)
    built, messages = world().environment_from_world(sky_world(bpy_module, path, 2.0))
    assert messages == [] and built.sun_tables[1] is not None
    stored = store.stats["stored"]  # the pixels and the environment
    again, _ = world().environment_from_world(sky_world(bpy_module, path, 2.0, "W2"))
    assert store.stats["stored"] == stored and store.stats["disk_hits"] == 1  # not even pixels
    for name, array in built.state().items():
        np.testing.assert_array_equal(again.state()[name], array, err_msg=name)
    # another strength is another environment: built again (its pixels from the disk)
    brighter, _ = world().environment_from_world(sky_world(bpy_module, path, 3.0, "W3"))
    assert store.stats["stored"] == stored + 1 and store.stats["disk_hits"] == 2
    assert brighter.mean_luminance == pytest.approx(1.5 * built.mean_luminance, rel=1e-6)


def test_a_damaged_environment_file_is_built_again(bpy_module, fresh_scene, store, tmp_path):
    path = sunny_sky(tmp_path / "sky.exr", 1)
    built, _ = world().environment_from_world(sky_world(bpy_module, path, 1.0))
    kept = {p: p.stat().st_size for p in store.folder().glob("*.npz")}
    largest = max(kept, key=kept.get)  # the environment: the pixels and its tables
    data = bytearray(largest.read_bytes())
    data[len(data) // 2] ^= 0xFF  # one byte in the middle of an array
    largest.write_bytes(bytes(data))
    again, _ = world().environment_from_world(sky_world(bpy_module, path, 1.0, "W2"))
    assert store.stats["rejected"] == 1
    for name, array in built.state().items():
        np.testing.assert_array_equal(again.state()[name], array, err_msg=name)


def test_an_environment_too_large_for_the_folder_is_not_kept(
    bpy_module, fresh_scene, store, tmp_path, monkeypatch
):
    path = sunny_sky(tmp_path / "sky.exr", 1)
    # 32 × 64 pixels: 24 kB of radiance, ~40 kB of state; a quarter of 100 kB holds the
    # pixels alone
    monkeypatch.setattr(store, "cap_bytes", 100_000)
    built, _ = world().environment_from_world(sky_world(bpy_module, path, 1.0))
    assert store.stats["stored"] == 1  # the pixels only
    again, _ = world().environment_from_world(sky_world(bpy_module, path, 1.0, "W2"))
    assert store.stats["disk_hits"] == 1 and store.stats["stored"] == 1  # pixels from disk
    for name, array in built.state().items():
        np.testing.assert_array_equal(again.state()[name], array, err_msg=name)

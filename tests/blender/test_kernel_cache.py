"""The installed extension keeps compiled OpenCL kernels and BTF importance tables in its user
directory (removed with the extension), not in ~/.cache."""

from __future__ import annotations

import importlib
from pathlib import Path

from blender_helpers import EXTENSION_MODULE


def test_kernel_cache_lives_in_the_extensions_user_directory(bpy_module, installed):
    programs = importlib.import_module(f"{EXTENSION_MODULE}.btf_addon.cl.programs")
    folder = Path(bpy_module.utils.extension_path_user(EXTENSION_MODULE, path="kernel_cache"))
    assert programs.configured_cache_dir() == folder
    assert programs.cache_dir() == folder and folder.is_dir()


def test_importance_tables_live_in_the_extensions_user_directory(bpy_module, installed):
    table_cache = importlib.import_module(f"{EXTENSION_MODULE}.btf_addon.core.sampling.table_cache")
    folder = Path(bpy_module.utils.extension_path_user(EXTENSION_MODULE, path="importance_cache"))
    assert table_cache.cache_dir() == folder


def test_bvhs_live_in_the_extensions_user_directory(bpy_module, installed):
    geometry_cache = importlib.import_module(f"{EXTENSION_MODULE}.btf_addon.scene.geometry_cache")
    folder = Path(bpy_module.utils.extension_path_user(EXTENSION_MODULE, path="geometry_cache"))
    assert geometry_cache.STORE.folder() == folder


def test_world_images_live_in_the_extensions_user_directory(bpy_module, installed):
    world_cache = importlib.import_module(
        f"{EXTENSION_MODULE}.btf_addon.blender.export.world_cache"
    )
    folder = Path(bpy_module.utils.extension_path_user(EXTENSION_MODULE, path="world_cache"))
    assert world_cache.STORE.folder() == folder

"""Importance tables on disk between sessions (core/sampling/table_cache.py): a new object of
the same material reads the stored table, equal to a fresh build; other content, other keys;
a damaged file is rebuilt and replaced; an unwritable folder or the cache turned off only
costs the build."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.packed import pack
from btf_addon.core.sampling import btf_importance, table_cache


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "importance"
    table_cache.set_cache_dir(folder)
    monkeypatch.setattr(table_cache, "stats", dict.fromkeys(table_cache.stats, 0))
    yield folder
    table_cache.set_cache_dir(None)


def material(albedo=(0.8, 0.5, 0.3)):
    """A fresh measured (dense) material object each call: no table in memory yet."""
    return tabulate(GGXBTF(albedo, 0.3), width=2, height=2)


def table_of(btf) -> np.ndarray:
    """The density the packed material carries (what the kernels sample)."""
    pack(btf, importance=True)
    return btf_importance.importance_table(btf).density


def test_a_new_object_of_the_same_material_reads_the_stored_table(cache):
    first = table_of(material())
    assert table_cache.stats == {"disk_hits": 0, "stored": 1, "rejected": 0}
    assert len(list(cache.glob("*.npy"))) == 1
    second = material()
    again = table_of(second)
    assert table_cache.stats["disk_hits"] == 1 and table_cache.stats["stored"] == 1
    # The independent check: a build from scratch, not through the cache.
    np.testing.assert_array_equal(again, btf_importance.build(second).density)
    np.testing.assert_array_equal(again, first)


def test_other_content_is_another_key(cache):
    table_of(material((0.8, 0.5, 0.3)))
    other = material((0.2, 0.5, 0.9))
    table_of(other)
    assert table_cache.stats["disk_hits"] == 0 and table_cache.stats["stored"] == 2
    assert len(list(cache.glob("*.npy"))) == 2


def test_the_key_covers_parameters_and_code():
    a = [np.arange(4, dtype=np.float32)]
    key = table_cache.table_key(a, {"grid": 24}, [btf_importance])
    assert table_cache.table_key(a, {"grid": 24}, [btf_importance]) == key
    assert table_cache.table_key(a, {"grid": 16}, [btf_importance]) != key
    assert table_cache.table_key(a, {"grid": 24}, [table_cache]) != key
    as_ints = [np.arange(4, dtype=np.float32).view(np.int32)]  # same bytes, other dtype
    assert table_cache.table_key(as_ints, {"grid": 24}, [btf_importance]) != key


@pytest.mark.parametrize(
    "damage",
    ["truncated", "not npy", "wrong shape", "nan", "below the floor", "float64"],
)
def test_a_damaged_file_is_rebuilt_and_replaced(cache, damage, caplog):
    good = table_of(material())
    (path,) = cache.glob("*.npy")
    shape = good.shape
    if damage == "truncated":
        path.write_bytes(path.read_bytes()[:200])
    elif damage == "not npy":
        path.write_bytes(b"\x00" * 1000)
    elif damage == "wrong shape":
        np.save(path, np.ones((shape[0], shape[1] - 1, shape[2]), np.float32))
    elif damage == "nan":
        np.save(path, np.where(np.arange(good.size).reshape(shape) == 7, np.nan, good))
    elif damage == "below the floor":
        np.save(path, np.full(shape, btf_importance.DEFENSIVE * 0.5, np.float32))
    else:
        np.save(path, good.astype(np.float64))
    with caplog.at_level(logging.WARNING):
        rebuilt = table_of(material())
    assert table_cache.stats["rejected"] == 1 and table_cache.stats["disk_hits"] == 0
    assert "building it again" in caplog.text
    np.testing.assert_array_equal(rebuilt, good)
    np.testing.assert_array_equal(np.load(path), good)  # replaced: the next session reads it
    table_of(material())
    assert table_cache.stats["disk_hits"] == 1


def test_an_unwritable_folder_costs_only_the_build(tmp_path, monkeypatch, caplog):
    blocker = tmp_path / "a file"
    blocker.write_text("in the way")
    table_cache.set_cache_dir(blocker / "importance")
    try:
        with caplog.at_level(logging.WARNING):
            first = table_of(material())
            second = table_of(material())
    finally:
        table_cache.set_cache_dir(None)
    np.testing.assert_array_equal(first, second)
    assert caplog.text.count("cannot write in") == 1  # said once, not per table


def test_off_turns_the_cache_off(tmp_path, monkeypatch):
    monkeypatch.setenv("BTF_TABLE_CACHE", "off")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert table_cache.cache_dir() is None
    table_of(material())
    assert not any(tmp_path.rglob("*.npy"))
    monkeypatch.setenv("BTF_TABLE_CACHE", str(tmp_path / "here"))
    assert table_cache.cache_dir() == tmp_path / "here"
    monkeypatch.delenv("BTF_TABLE_CACHE")
    assert table_cache.cache_dir() == tmp_path / "btf_materials" / "importance"

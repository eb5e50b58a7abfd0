"""Environment.state / from_state (core/sampling/envmap.py): the World's environment kept on
disk between sessions (blender/export/world_cache.py) must come back as the very Environment
that was built, table for table and bit for bit, and anything else read back must be refused."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import studiolights_dir

from btf_addon.core.formats.imageio import read_exr
from btf_addon.core.sampling.envmap import Environment


def bundled(name: str) -> np.ndarray:
    return read_exr(studiolights_dir() / f"{name}.exr")[..., :3]


def sky_with_sun(rng) -> np.ndarray:
    sky = rng.gamma(2.0, 0.5, (64, 128, 3)).astype(np.float32)
    sky[10:12, 40:42] = 5000.0  # a compact source far above the mean: a sun
    return sky


MAPS = {
    # forest.exr has a sun and patchy light beside it (sun tables and a lobe window),
    # city.exr a sun and no window (docs/accuracy.md, "The lobe window")
    "forest": lambda rng: bundled("forest"),  # skips where bpy is not installed
    "city": lambda rng: bundled("city"),
    "sun": sky_with_sun,
    "smooth": lambda rng: rng.uniform(0.5, 1.0, (16, 32, 3)),  # no sun: mis tables only
    "black": lambda rng: np.zeros((8, 16, 3), np.float32),
    "nan and negative": lambda rng: np.where(
        rng.uniform(size=(16, 32, 3)) < 0.1, np.nan, rng.normal(1.0, 1.0, (16, 32, 3))
    ).astype(np.float32),
}


def round_trip(env: Environment, rotation: float) -> Environment:
    # copies, as a read from disk gives: nothing shared with the built Environment
    state = {name: np.array(array) for name, array in env.state().items()}
    assert Environment.valid_state(state)
    return Environment.from_state(state, rotation)


def assert_same_tables(a, b):
    assert type(a) is type(b)
    for x, y in zip(a, b, strict=True):
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype
            np.testing.assert_array_equal(x, y)
        else:
            assert x == y


@pytest.mark.parametrize("name", list(MAPS))
def test_from_state_is_the_environment_that_was_built(name, rng):
    built = Environment(MAPS[name](rng), strength=1.7, rotation_z_rad=0.4)
    back = round_trip(built, 0.4)
    tables, sun = built.sun_tables
    back_tables, back_sun = back.sun_tables
    assert_same_tables(tables, back_tables)
    assert (sun is None) == (back_sun is None)
    if sun is not None:
        assert_same_tables(sun, back_sun)
    assert (built.lobe_window is None) == (back.lobe_window is None)
    if built.lobe_window is not None:
        assert_same_tables(built.lobe_window, back.lobe_window)
    # what state() does not keep is built again from the radiance, to the same values
    assert_same_tables(built.mis_tables, back.mis_tables)
    assert_same_tables(built.tables, back.tables)
    np.testing.assert_array_equal(built.rgba32(), back.rgba32())
    for field in ("mean_luminance", "is_black", "nonfinite_count", "negative_count", "width"):
        assert getattr(built, field) == getattr(back, field), field
    directions = rng.normal(size=(200, 3))
    np.testing.assert_array_equal(built.pdf(directions), back.pdf(directions))
    np.testing.assert_array_equal(built.lookup(directions), back.lookup(directions))
    u = rng.uniform(size=(50, 2))
    for x, y in zip(built.sample(u), back.sample(u), strict=True):
        np.testing.assert_array_equal(x, y)


def test_the_maps_cover_every_kind_of_state(rng):
    """The cases above differ where the state differs: with and without a sun and a window."""
    sun = Environment(sky_with_sun(rng)).state()
    smooth = Environment(MAPS["smooth"](rng)).state()
    assert "sun_pixels" in sun and "sun_pixels" not in smooth
    # a float32 map (Blender's) keeps its RGBA texture, a float64 one its radiance as it is
    assert "rgba" in sun and "radiance" not in sun
    assert "radiance" in smooth and smooth["radiance"].dtype == np.float64
    assert "window_block" in Environment(bundled("forest")).state()  # skips without bpy
    assert "window_block" not in Environment(bundled("city")).state()


def test_rotation_is_the_callers(rng):
    sky = sky_with_sun(rng)
    back = round_trip(Environment(sky, rotation_z_rad=0.4), 1.1)
    assert back.rotation_z_rad == 1.1
    turned = Environment(sky, rotation_z_rad=1.1)
    directions = rng.normal(size=(100, 3))
    np.testing.assert_array_equal(back.lookup(directions), turned.lookup(directions))


def damaged(state: dict, how: str) -> dict:
    state = {name: np.array(array) for name, array in state.items()}
    if how == "missing":
        del state["tables_col_cdf"]
    elif how == "extra":
        state["stranger"] = np.zeros(3)
    elif how == "dtype":
        state["tables_col_pdf"] = state["tables_col_pdf"].astype(np.float64)
    elif how == "shape":
        state["tables_row_cdf"] = state["tables_row_cdf"][:-1]
    elif how == "radiance shape":
        state["rgba"] = state["rgba"][:, :-1]
    elif how == "rgb, not rgba":
        state["rgba"] = state["rgba"][..., :3]
    elif how == "sun shape":
        state["sun_cdf"] = state["sun_cdf"][:-1]
    elif how == "window shape":
        state["window_cdf"] = state["window_cdf"][:, :-1]
    elif how == "window block":
        state["window_block"] = state["window_block"] * 2
    elif how == "sun outside the map":
        state["sun_pixels"][-1] = state["rgba"].shape[0] * state["rgba"].shape[1]
    elif how == "not finite":
        state["tables_col_cdf"].flat[7] = np.nan
    elif how == "scalars":
        state["scalars"] = state["scalars"][:4]
    return state


@pytest.mark.parametrize(
    "how",
    [
        "missing",
        "extra",
        "dtype",
        "shape",
        "radiance shape",
        "rgb, not rgba",
        "sun shape",
        "window shape",
        "window block",
        "sun outside the map",
        "not finite",
        "scalars",
    ],
)
def test_a_state_that_is_not_one_is_refused(how):
    state = Environment(bundled("forest")).state()  # with a sun and a window: every array
    assert Environment.valid_state(damaged(state, "none"))
    assert not Environment.valid_state(damaged(state, how))

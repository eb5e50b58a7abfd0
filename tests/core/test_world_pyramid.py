"""The World's pyramid (core/sampling/world_pyramid.py): its layout as both back ends find it,
and what averaging must keep (a constant stays constant, the light over the sphere is kept at
every level, hard cases: odd sizes, one pixel, a map of zeros and of huge values)."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.sampling.envmap import Environment
from btf_addon.core.sampling.world_pyramid import level_count, level_size, world_pyramid


def _levels(pyramid):
    row = 0
    for k in range(pyramid.levels):
        w, h = level_size(pyramid.width, pyramid.height, k)
        yield pyramid.rgba[row : row + h, :w, :3].astype(np.float64), h
        row += h


def _sphere_total(level: np.ndarray) -> np.ndarray:
    """∫ L dω over the sphere with each pixel's solid angle (2π/w)·(π/h)·sin θ of its row's
    centre (the weights the pyramid averages with)."""
    h, w = level.shape[:2]
    sin = np.sin((np.arange(h) + 0.5) / h * np.pi)
    return (level * sin[:, None, None]).sum(axis=(0, 1)) * (2 * np.pi / w) * (np.pi / h)


@pytest.mark.parametrize("shape", [(64, 128), (37, 75), (1, 1), (8, 3), (2, 64)])
def test_levels_are_stacked_as_the_shaders_find_them(shape):
    h, w = shape
    image = np.random.default_rng(0).uniform(0.0, 5.0, (h, w, 3))
    pyramid = world_pyramid(Environment(image))
    assert pyramid.levels == level_count(w, h) == max(w, h).bit_length()
    rows = sum(max(h >> k, 1) for k in range(pyramid.levels))
    # the levels, then the suns' row (none here: no pixel reaches 16 × the mean)
    assert pyramid.rgba.shape == (rows + 1, w, 4) and pyramid.rgba.dtype == np.float32
    assert pyramid.suns == 0 and pyramid.rgba[rows, 0, 3] == 0.0
    levels = list(_levels(pyramid))
    # level 0 is the map itself; the last is one pixel
    np.testing.assert_allclose(levels[0][0], image, rtol=1e-6)
    assert levels[-1][0].shape[:2] == (1, 1)
    # alpha 1 inside every level, 0 in the unused columns right of it
    assert np.all(pyramid.rgba[..., 3] >= 0.0) and pyramid.rgba[0, 0, 3] == 1.0


def test_a_constant_world_stays_constant_at_every_level():
    image = np.full((45, 90, 3), (0.2, 0.5, 3.0))
    pyramid = world_pyramid(Environment(image))
    for level, _ in _levels(pyramid):
        np.testing.assert_allclose(level, np.broadcast_to((0.2, 0.5, 3.0), level.shape), rtol=1e-6)


def _suns(pyramid):
    row = pyramid.rgba[-1].astype(np.float64)
    return row[0 : 2 * pyramid.suns : 2, :3], row[1 : 2 * pyramid.suns : 2, :3]


def test_every_level_and_the_suns_keep_the_light_over_the_sphere():
    """Averaging by solid angle moves light, never makes or loses it: ∫ L dω of every level
    plus the suns' power equals the map's to 1 % (the rows' sin θ at their centres is a
    midpoint rule, so a level of h rows integrates sin θ to (π/2h)² / 6 relative: 1e-3 at
    h = 16, 0.8 at h = 1, which the small levels are not held to). A bright sun of 3 pixels
    near the horizon (17 % of the map's light) leaves the map for one sun at its direction."""
    image = np.random.default_rng(1).uniform(0.0, 1.0, (128, 256, 3))
    image[70, 40:43] = 5e4
    env = Environment(image)
    pyramid = world_pyramid(env)
    directions, power = _suns(pyramid)
    assert pyramid.suns == 1
    # the middle pixel's centre, in the map's frame (envmap.directions_from_image_coords):
    # the normalised mean of three directions 1.4° apart leans 3e-5 towards the pole
    expected = env.directions_from_image_coords(np.array([41.5 / 256]), np.array([70.5 / 128]))
    np.testing.assert_allclose(directions[0], expected[0], atol=1e-4)
    total = _sphere_total(image)
    luminance = np.array([0.2126, 0.7152, 0.0722])
    sin = np.sin((np.arange(128) + 0.5) / 128 * np.pi)
    mean = ((image @ luminance) * sin[:, None]).sum() / (sin.sum() * 256)  # the sun's too
    for level, h in _levels(pyramid):
        assert (level @ luminance).max() <= 16 * mean * (1 + 1e-6)  # nothing above is left
        if h >= 8:
            np.testing.assert_allclose(_sphere_total(level) + power[0], total, rtol=0.01)
    assert power[0] @ [0.2126, 0.7152, 0.0722] > 0.15 * (total @ [0.2126, 0.7152, 0.0722])


def test_scattered_bright_pixels_become_at_most_max_suns():
    """Bright pixels all over the map (sky through leaves) are summed per block into at most
    MAX_SUNS directional lights, their power kept."""
    from btf_addon.core.sampling.world_pyramid import MAX_SUNS

    rng = np.random.default_rng(2)
    image = rng.uniform(0.0, 1.0, (64, 128, 3))
    image[rng.integers(0, 64, 300), rng.integers(0, 128, 300)] = 400.0
    env = Environment(image)
    pyramid = world_pyramid(env)
    directions, power = _suns(pyramid)
    assert 1 < pyramid.suns <= MAX_SUNS
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, rtol=1e-5)
    level0 = next(_levels(pyramid))[0]
    np.testing.assert_allclose(
        _sphere_total(level0) + power.sum(axis=0), _sphere_total(image), rtol=1e-5
    )


def test_hard_values_stay_finite():
    """Zeros, huge HDR values and NaN/Inf pixels (cleaned to 0 by Environment) average to
    finite levels; a black World's pyramid is black."""
    image = np.zeros((16, 32, 3))
    image[3, 5] = (np.nan, np.inf, -np.inf)
    image[8, 9] = 3e38
    pyramid = world_pyramid(Environment(image))
    assert np.all(np.isfinite(pyramid.rgba))
    assert world_pyramid(Environment(np.zeros((16, 32, 3)))).rgba[..., :3].max() == 0.0


def test_the_pyramid_is_built_once_per_environment():
    env = Environment(np.ones((8, 16, 3)))
    assert world_pyramid(env) is world_pyramid(env)


def test_a_large_map_is_halved_to_max_width_first(monkeypatch):
    """A map wider than MAX_WIDTH gives a pyramid whose level 0 is its halving (the bound on
    GPU memory): the light over the sphere kept, the suns taken from the full map."""
    import btf_addon.core.sampling.world_pyramid as module

    monkeypatch.setattr(module, "MAX_WIDTH", 64)
    image = np.random.default_rng(3).uniform(0.0, 1.0, (128, 256, 3))
    image[40, 100] = 1e5
    pyramid = module.world_pyramid(Environment(image))
    assert (pyramid.width, pyramid.height) == (64, 32)
    assert pyramid.rgba.shape[1] == 64 and pyramid.suns == 1
    level0 = next(_levels(pyramid))[0]
    power = _suns(pyramid)[1][0]
    np.testing.assert_allclose(_sphere_total(level0) + power, _sphere_total(image), rtol=0.01)

"""A batch of lights gives the same image however many lights it holds (issue 30 item 5: at
255–256 lights in one draw, llvmpipe drew a dense woven BTF up to 8 % darker in bands; 1, 64
and 128 agreed to 2e-7). Batches are drawn in pieces of at most MAX_LIGHTS_PER_DRAW lights,
added up. Tolerance 1e-6 relative RMSE: the same sums in another order in float32."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.grid import UBO2003
from btf_addon.core.sampling.envmap import Environment
from btf_addon.gl import drawer as drawer_module
from btf_addon.gl.renderer import GLSLRenderer
from btf_addon.render.pixel_filter import PixelFilter
from btf_addon.scene.primitives import uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at


@pytest.fixture(scope="module")
def woven_sphere():
    rng = np.random.default_rng(1)
    btf = tabulate(woven(texels=4, fine_per_texel=2), UBO2003, UBO2003)
    return Scene(
        [uv_sphere(1.0, segments=24, rings=12)],
        [Material(btf)],
        Camera(look_at((0.0, -3.5, 0.5), (0.0, 0.0, 0.0))),
        Environment(rng.gamma(0.7, 1.0, size=(16, 32, 3))),
    )


def _rel(a, b) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b**2)))


def test_batches_of_8_64_256_and_512_lights_agree(woven_sphere):
    lights = woven_sphere.environment.virtual_lights(512, seed=0)
    renderer = GLSLRenderer(woven_sphere, 40, 30)
    try:
        images = {k: renderer.render(lights, k) for k in (8, 64, 256, 512)}
    finally:
        renderer.release()
    assert images[8].mean() > 0.01
    for k in (64, 256, 512):
        assert _rel(images[k], images[8]) < 1e-6, k


def test_a_jittered_batch_in_pieces_is_the_batch_whole(woven_sphere, monkeypatch):
    """With anti-aliasing each batch is drawn at its own subpixel offset, so the pieces of a
    batch (the first replacing the World under the surface, the others added) must sum to
    what one draw gives: pieces of 32 against pieces of 128."""
    lights = woven_sphere.environment.virtual_lights(256, seed=0)
    images = []
    for most in (128, 32):
        monkeypatch.setattr(drawer_module, "MAX_LIGHTS_PER_DRAW", most)
        renderer = GLSLRenderer(woven_sphere, 40, 30)
        renderer.view.jitter = PixelFilter()
        try:
            images.append(renderer.render(lights, 128))
        finally:
            renderer.release()
    assert _rel(images[1], images[0]) < 1e-6

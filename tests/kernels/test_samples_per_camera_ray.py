"""Samples per Camera Ray (issue 33): consecutive samples of a pixel share one camera ray
through the pixel filter (kernels/render_direct.cl ``camera_split``).

Checked by what sharing means, independently of our earlier images: Film › Transparent's alpha
is the fraction of a pixel's samples whose camera ray met a surface, so with groups of k
samples sharing a ray every alpha is a multiple of 1/k (also when a launch starts inside a
group, which traces the group's ray again), and with 1 the silhouette has alphas between.
And sharing changes no expectation: the mean of many seeds equals that of a ray per sample
within the seeds' own noise. A pixel under a sharp GGX lobe takes a ray per sample whatever
the split: its image is the one of a ray per sample, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import studiolights_dir

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.formats.imageio import read_exr
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene.primitives import uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

pytestmark = pytest.mark.opencl

W, H = 20, 14


@pytest.fixture(scope="module")
def renderer(cl_context):
    from btf_addon.cl.renderer import CLRenderer

    scene = Scene(
        [uv_sphere(1.0, 24, 12)],
        [Material(GGXBTF(0.8, 0.3))],  # glossy: lighting that varies within a footprint
        Camera(look_at((0.0, -3.2, 0.6), (0, 0, 0))),  # the silhouette crosses many pixels
        Environment(read_exr(studiolights_dir() / "forest.exr")),
    )
    r = CLRenderer(scene, W, H, cl_context)
    r.fixed_launch_split = True  # launches of 4 samples: groups of 8 straddle them
    return r


def _render(renderer, split: int, samples: int, seed: int, transparent: bool = False):
    renderer.samples_per_camera_ray = split
    renderer.transparent = transparent
    try:
        return renderer.render_sampled(samples, seed=seed)
    finally:
        renderer.transparent = False


@pytest.mark.parametrize("split", [4, 8])
def test_samples_of_a_group_share_their_camera_ray(renderer, split):
    alpha = _render(renderer, split, 16, seed=1, transparent=True)[..., 3]
    groups = alpha * (16 // split)
    # float32 k/n sums: 1e-5
    np.testing.assert_allclose(groups, np.round(groups), atol=1e-5)
    edge = (alpha > 0) & (alpha < 1)
    assert edge.sum() >= 10  # the silhouette is there, so the check above could fail


def test_a_ray_per_sample_sees_the_footprint_finer(renderer):
    alpha = _render(renderer, 1, 16, seed=1, transparent=True)[..., 3]
    quarters = alpha * 4
    assert np.abs(quarters - np.round(quarters)).max() > 0.1  # alphas between the quarters


def test_sharing_changes_no_expectation(renderer):
    """8 seeds × 64 samples each way. Per pixel, the two means differ by less than 4.5
    standard errors of their difference (estimated from the seeds' spread; at 280 pixels a
    false alarm has odds of about 1 in 500 per pixel under a normal law, hence at most 2
    pixels may exceed it) and the image means by less than 0.5 %."""
    seeds = range(8)
    one = np.stack([_render(renderer, 1, 64, s)[..., :3] for s in seeds])
    four = np.stack([_render(renderer, 4, 64, s + 100)[..., :3] for s in seeds])
    diff = one.mean(axis=0) - four.mean(axis=0)
    se = np.sqrt(one.var(axis=0, ddof=1) / 8 + four.var(axis=0, ddof=1) / 8)
    outside = np.abs(diff) > 4.5 * se + 1e-6
    assert outside.any(axis=-1).sum() <= 2, np.argwhere(outside)
    assert abs(float(four.mean()) / float(one.mean()) - 1.0) < 0.005


def interior(alpha: np.ndarray) -> np.ndarray:
    """Pixels whose 3 × 3 neighbourhood is fully covered: their centre ray meets the sphere."""
    full = alpha >= 1.0
    inner = full.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            inner &= np.roll(np.roll(full, dy, axis=0), dx, axis=1)
    inner[[0, -1], :] = inner[:, [0, -1]] = False
    return inner


def test_a_sharp_lobe_takes_a_ray_per_sample(cl_context, renderer):
    """Under a GGX lobe below SHARP_LOBE_ALPHA2 (roughness 0.2: α² = 0.0016) a pixel takes a
    camera ray per sample whatever the split asks (render_direct.cl sharp_lobe_at_centre): its
    covered pixels are those of a ray per sample, bit for bit. The module's roughness 0.3
    sphere (α² = 0.0081) keeps the groups: the same pixels differ, so the check could fail."""
    from btf_addon.cl.renderer import CLRenderer

    sharp_scene = Scene(
        [uv_sphere(1.0, 24, 12)],
        [Material(GGXBTF(0.8, 0.2))],
        renderer.scene.camera,
        renderer.scene.environment,
    )
    sharp = CLRenderer(sharp_scene, W, H, cl_context)
    sharp.fixed_launch_split = True
    covered = interior(_render(sharp, 1, 16, seed=3, transparent=True)[..., 3])
    assert covered.sum() >= 20
    one, four = (_render(sharp, k, 16, seed=3)[covered] for k in (1, 4))
    np.testing.assert_array_equal(four, one)
    rough_one, rough_four = (_render(renderer, k, 16, seed=3)[covered] for k in (1, 4))
    assert (rough_four != rough_one).any(axis=-1).mean() > 0.5

"""Kernel variants by what the scene has (btf_addon/scene/analysis.py): a specialised program
renders the same image as the program with every path compiled, bit for bit (the paths left
out contribute exactly nothing, and the random numbers they would draw are still drawn)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import shared_material

from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene.analysis import SceneFeatures, analyse
from btf_addon.scene.lights import PointLight, SunLight
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

pytestmark = pytest.mark.opencl


def _scene(lights):
    ground = plane(6.0, material=0)
    ground.world_from_object = np.eye(4)
    ground.world_from_object[2, 3] = -1.0
    btf = MLVQBTF.from_directory(shared_material("alu"))
    return Scene(
        [uv_sphere(1.0, 24, 12), ground],
        [Material(btf, uv_scale=2.0)],
        Camera(look_at((0.0, -4.0, 1.0), (0, 0, 0))),
        Environment.constant((0.0, 0.0, 0.0)),  # black World
        lights=lights,
    )


@pytest.mark.parametrize("kind", ["sun", "point"])
def test_specialised_program_renders_the_same_frame(cl_context, kind):
    from btf_addon.cl.renderer import CLRenderer

    light = (
        SunLight(np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]), np.ones(3) * 3)
        if kind == "sun"
        else PointLight(np.array([1.0, -2.0, 2.5]), np.ones(3) * 40.0, radius=0.2)
    )
    scene = _scene([light])
    features = analyse(scene)
    defines = features.defines()
    assert defines["HAS_ENVIRONMENT"] == 0 and defines["HAS_AREA_LIGHTS"] == 0
    assert defines["HAS_MLVQ"] == 1 and defines["HAS_DENSE"] == 0 and defines["HAS_ANALYTIC"] == 0
    assert defines["HAS_SUN_LIGHTS"] == (kind == "sun")
    assert defines["HAS_POINT_LIGHTS"] == (kind == "point")
    full = SceneFeatures(shadows=True, environment_texture=False)  # every path compiled
    images = []
    for f in (features, full):
        renderer = CLRenderer(scene, 24, 16, cl_context, f)
        renderer.fixed_launch_split = True  # same launches, same float sums
        images.append(renderer.render_sampled(6, seed=5, max_bounces=1))
    assert images[0][..., :3].max() > 0  # the light reaches the frame
    np.testing.assert_array_equal(images[0], images[1])

"""Which kernel variant a scene needs (btf_addon/scene/analysis.py defines)."""

from __future__ import annotations

import numpy as np

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene.analysis import ALL_CODECS, SceneFeatures, analyse
from btf_addon.scene.lights import AreaLight, PointLight, SunLight
from btf_addon.scene.primitives import uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at


def _scene(btfs, env, lights):
    return Scene(
        [uv_sphere(1.0, 8, 4)],
        [Material(b) for b in btfs],
        Camera(look_at((0.0, -4.0, 1.0), (0, 0, 0))),
        env,
        lights=lights,
    )


def test_defines_follow_what_the_scene_has():
    black = Environment.constant((0.0, 0.0, 0.0))
    sun = SunLight(np.array([0.0, 0.0, 1.0]), np.ones(3))
    d = analyse(_scene([LambertianBTF(0.5)], black, [sun])).defines()
    assert d == {
        "HAS_SHADOWS": 0,
        "HAS_AREA_LIGHTS": 0,
        "HAS_SUN_LIGHTS": 1,
        "HAS_POINT_LIGHTS": 0,
        "HAS_ENVIRONMENT": 0,
        "HAS_MLVQ": 0,
        "HAS_DENSE": 0,
        "HAS_SVD": 0,
        "HAS_ANALYTIC": 1,
    }
    spot = PointLight(np.zeros(3), np.ones(3), axis=np.array([0, 0, -1.0]), cos_half_angle=0.5)
    area = AreaLight(np.zeros(3), np.array([0, 0, -1.0]), np.eye(3)[0], np.eye(3)[1], np.ones(3))
    grey = Environment.constant((0.2, 0.2, 0.2))
    d = analyse(_scene([GGXBTF(0.5, 0.3)], grey, [spot, area])).defines()
    assert d["HAS_POINT_LIGHTS"] == 1 and d["HAS_AREA_LIGHTS"] == 1 and d["HAS_SUN_LIGHTS"] == 0
    assert d["HAS_ENVIRONMENT"] == 1


def test_unknown_codec_and_hand_made_features_compile_everything():
    full = SceneFeatures(shadows=True, environment_texture=False).defines()
    assert all(v == 1 for v in full.values())
    assert ALL_CODECS <= SceneFeatures(True, False).codecs
    odd = SceneFeatures(True, False, codecs=frozenset({"some_new_codec"})).defines()
    assert odd["HAS_MLVQ"] == odd["HAS_DENSE"] == odd["HAS_SVD"] == odd["HAS_ANALYTIC"] == 1
    # 8 yes/no defines: at most 2^8 variants, the bound stated in analysis.py.
    assert len(full) == 9

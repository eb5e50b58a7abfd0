"""One F12 frame (cl/frame.py ``render_frame``) on one renderer whose film and texel filter
change between frames, as the accuracy report's rungs change them: every frame bit for bit
the frame of a renderer built for that film and filter, in either order, with the scene's BVH
built once. A checkerboard receding to the horizon at 24 × 16: both filters show there."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from aa_scenes import horizon_scene

from btf_addon.render.lighting import frame_lights
from btf_addon.render.settings import FinalMode, RenderSettings

pytestmark = pytest.mark.opencl

W, H = 24, 16

#: (settings, texel filter): the scene's own film and filter, then each changed.
FRAMES = (
    (RenderSettings(), None),
    (RenderSettings(use_antialiasing=False), "NEAREST"),
    (RenderSettings(pixel_filter="GAUSSIAN", filter_width=2.5), "LINEAR"),
    (RenderSettings(pixel_filter="BOX", filter_width=1.0), "NEAREST"),
)
MODES = (
    {"final_mode": FinalMode.SAMPLED, "samples": 4, "max_bounces": 1},
    {"final_mode": FinalMode.VIRTUAL, "lights_total": 8, "aa_samples": 4},
)


def frames():
    """Every (settings, texel filter) of FRAMES in both final modes."""
    # Bit for bit needs the fixed launch split (render/launch.py); render_frame takes it, as
    # every launch option, from the settings.
    return [(replace(s, **mode, fixed_launch_split=True), f) for s, f in FRAMES for mode in MODES]


def lights_of(settings, scene):
    return frame_lights(settings, scene, scene.camera.world_from_camera[:3, 2])


def built_for(cl_context, scene, settings, texel_filter):
    """The renderer of before: built for one film, on the scene with every material's texel
    filter replaced (what blender/accuracy/run.py kept one of per pair)."""
    from btf_addon.cl.renderer import CLRenderer

    if texel_filter is not None:
        materials = [replace(m, texel_filter=texel_filter) for m in scene.materials]
        scene = replace(scene, materials=materials)
    renderer = CLRenderer(scene, W, H, cl_context, film=settings.film())
    renderer.fixed_launch_split = True  # bit for bit needs the fixed split (render/launch.py)
    return renderer


def old_sequence(renderer, settings, lights):
    """F12's calls as blender/final_render.py made them before render_frame existed (with the
    Sampled mode's options issue 33 added: Clamp Indirect, Samples per Camera Ray, the Noise
    Threshold of adaptive sampling)."""
    if settings.sampled:
        renderer.clamp_indirect = settings.clamp_indirect
        renderer.samples_per_camera_ray = settings.samples_per_camera_ray
        renderer.adaptive_threshold = settings.noise_threshold
        passes = renderer.render_direct(lights.prefix(1))
        passes.combined = renderer.render_sampled(
            settings.samples, settings.seed, max_bounces=settings.max_bounces
        )
        return passes
    return renderer.render_direct(lights, aa_samples=settings.aa_samples)


def same_passes(a, b) -> bool:
    return all(
        np.array_equal(getattr(a, name), getattr(b, name))
        for name in ("combined", "depth", "normal", "uv")
    )


@pytest.fixture(scope="module")
def references(cl_context):
    """Each frame from a renderer built for its film and filter, by the calls of before."""
    scene = horizon_scene()
    return [
        old_sequence(built_for(cl_context, scene, s, f), s, lights_of(s, scene))
        for s, f in frames()
    ]


@pytest.mark.parametrize("order", ["forward", "backward"])
def test_one_renderer_switching_film_and_filter_renders_the_frames_of_before(
    cl_context, references, monkeypatch, order
):
    """Each frame bit for bit the reference, visiting the films and filters forwards then back
    again to the first (or the reverse), so every change is made both ways; and the scene's
    BVH built once, its buffers never uploaded again (before, only a renderer per film and
    filter could render them)."""
    from btf_addon.cl import renderer as renderer_module
    from btf_addon.cl.frame import render_frame

    builds = []
    real_build = renderer_module.cached_bvh

    def counting_build(*args, **kwargs):
        builds.append(1)
        return real_build(*args, **kwargs)

    monkeypatch.setattr(renderer_module, "cached_bvh", counting_build)
    scene = horizon_scene()
    renderer = renderer_module.CLRenderer(scene, W, H, cl_context)
    renderer.fixed_launch_split = True
    geometry = [renderer.bounds, renderer.links, renderer.corners, renderer.tri_material]
    visits = list(range(len(references)))
    visits = visits + visits[:2] if order == "forward" else visits[::-1] + visits[-2:][::-1]
    all_frames = frames()
    for i in visits:
        settings, texel_filter = all_frames[i]
        renderer.set_texel_filter(texel_filter)
        passes = render_frame(renderer, settings, lights_of(settings, scene))
        assert same_passes(passes, references[i]), (order, i, settings.film(), texel_filter)
        assert renderer.film == settings.film() and renderer.texel_filter == texel_filter
    assert len(builds) == 1
    now = [renderer.bounds, renderer.links, renderer.corners, renderer.tri_material]
    assert all(a is b for a, b in zip(now, geometry, strict=True))


def test_the_switches_show_in_the_image(references):
    """The test above can see a wrong film or texel filter: each changes the frame."""
    combined = [r.combined for r in references]
    for i in range(len(MODES)):  # per mode, FRAMES' four film and filter pairs all differ
        images = combined[i :: len(MODES)]
        for a in range(len(images)):
            for b in range(a + 1, len(images)):
                assert not np.array_equal(images[a], images[b]), (i, a, b)


def test_texel_filter_alone_changes_only_the_material_blocks(cl_context):
    """A texel filter travels in the material parameter blocks only; setting the one already
    set uploads nothing, and a film the same as the current one neither."""
    from btf_addon.cl.renderer import CLRenderer

    renderer = CLRenderer(horizon_scene(), W, H, cl_context)
    tables = [renderer.ints, renderer.floats, renderer.material_offsets, renderer.filter_table]
    blocks = renderer.material_params
    renderer.set_texel_filter(None)
    renderer.set_film(RenderSettings().film())
    assert renderer.material_params is blocks and renderer.filter_table is tables[-1]
    renderer.set_texel_filter("NEAREST")
    assert renderer.material_params is not blocks
    now = [renderer.ints, renderer.floats, renderer.material_offsets]
    assert all(a is b for a, b in zip(now, tables[:3], strict=True))
    with pytest.raises(ValueError, match="texel filter"):
        renderer.set_texel_filter("CUBIC")
    assert renderer.texel_filter == "NEAREST"


def test_the_launch_options_come_from_the_settings(cl_context):
    """render_frame launches as F12 launched: BTF importance sampling, the fixed launch split
    and Film › Transparent from its arguments, whatever the renderer held before (the
    accuracy report's renderer was left at its defaults, so a scene that turned importance
    sampling off or rendered a transparent film was measured with other launches than F12's)."""
    from btf_addon.cl.frame import render_frame
    from btf_addon.cl.renderer import CLRenderer

    scene = horizon_scene()
    settings = replace(
        RenderSettings(**MODES[0]), btf_importance_sampling=False, fixed_launch_split=True
    )
    renderer = CLRenderer(scene, W, H, cl_context)
    renderer.importance_sampling, renderer.fixed_launch_split = True, None
    got = render_frame(renderer, settings, lights_of(settings, scene), transparent=True)
    assert (renderer.importance_sampling, renderer.fixed_launch_split) == (False, True)
    assert renderer.transparent is True
    assert renderer.samples_per_camera_ray == settings.samples_per_camera_ray == 4
    assert renderer.adaptive_threshold == settings.noise_threshold == pytest.approx(0.01)
    by_hand = CLRenderer(scene, W, H, cl_context)
    by_hand.importance_sampling, by_hand.fixed_launch_split, by_hand.transparent = (
        False,
        True,
        True,
    )
    assert same_passes(got, old_sequence(by_hand, settings, lights_of(settings, scene)))

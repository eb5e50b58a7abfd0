"""RenderSettings without Blender: overrides, conversion from and to property objects."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from btf_addon.render.settings import FinalMode, Lighting, RenderSettings


def test_with_overrides_keeps_what_is_none():
    base = RenderSettings(lights_total=7, seed=3)
    same = base.with_overrides(lights_total=None, seed=None, final_mode=None)
    assert same == base
    changed = base.with_overrides(samples=16, final_mode=FinalMode.SAMPLED, seed=None)
    assert (changed.samples, changed.final_mode, changed.seed) == (16, FinalMode.SAMPLED, 3)
    assert changed.lights_total == 7
    with pytest.raises(TypeError):
        base.with_overrides(no_such_field=1)


def test_properties_round_trip_by_enum_name():
    props = SimpleNamespace()
    settings = RenderSettings(lighting=Lighting.HEADLIGHT, final_mode=FinalMode.SAMPLED)
    settings.to_properties(props)
    assert props.lighting == "HEADLIGHT" and props.final_mode == "SAMPLED"
    assert RenderSettings.from_properties(props) == settings
    props.final_mode = "ENVMAP"  # not an identifier: an error, not a silent default
    with pytest.raises(KeyError):
        RenderSettings.from_properties(props)


def test_sampled_only_under_the_world():
    assert RenderSettings(final_mode=FinalMode.SAMPLED).sampled
    assert not RenderSettings(final_mode=FinalMode.VIRTUAL).sampled
    headlight = RenderSettings(final_mode=FinalMode.SAMPLED, lighting=Lighting.HEADLIGHT)
    assert not headlight.sampled  # one deterministic light: rendered as Virtual Lights


def test_the_film_filter_comes_from_the_scenes_cycles_settings():
    props = SimpleNamespace()
    RenderSettings().to_properties(props)
    assert not hasattr(props, "pixel_filter")  # kept on the scene's film, not btf_render
    plain = SimpleNamespace(btf_render=props)  # no Cycles add-on: Blender's default film
    assert RenderSettings.from_scene(plain) == RenderSettings()
    cycles = SimpleNamespace(pixel_filter_type="GAUSSIAN", filter_width=2.5)
    settings = RenderSettings.from_scene(SimpleNamespace(btf_render=props, cycles=cycles))
    assert (settings.pixel_filter, settings.filter_width) == ("GAUSSIAN", 2.5)

"""The VR action set as data (plain Python): every action maps to the shared vocabulary, every
binding names a component its interaction profile has (the lists below are written from the
OpenXR 1.0 specification, section 6.4 "Interaction Profile Paths", independently of the
module), and no two actions share an input of one hand."""

from __future__ import annotations

import re

import pytest

from btf_addon.controllers import xr_bindings as xb
from btf_addon.controllers.actions import CONTINUOUS, Action

LEFT, RIGHT = "/user/hand/left", "/user/hand/right"
POSES = {"/input/grip/pose", "/input/aim/pose"}

# OpenXR 1.0, 6.4: supported component paths per interaction profile and hand. "system/click"
# is listed by the spec as possibly unavailable to applications, so it is left out here.
SPEC: dict[str, dict[str, set[str]]] = {
    "/interaction_profiles/khr/simple_controller": {
        hand: {"/input/select/click", "/input/menu/click", *POSES} for hand in (LEFT, RIGHT)
    },
    "/interaction_profiles/htc/vive_controller": {
        hand: {
            "/input/squeeze/click",
            "/input/menu/click",
            "/input/trigger/click",
            "/input/trigger/value",
            "/input/trackpad/x",
            "/input/trackpad/y",
            "/input/trackpad/click",
            "/input/trackpad/touch",
            *POSES,
        }
        for hand in (LEFT, RIGHT)
    },
    "/interaction_profiles/microsoft/motion_controller": {
        hand: {
            "/input/menu/click",
            "/input/squeeze/click",
            "/input/trigger/value",
            "/input/thumbstick/x",
            "/input/thumbstick/y",
            "/input/thumbstick/click",
            "/input/trackpad/x",
            "/input/trackpad/y",
            "/input/trackpad/click",
            "/input/trackpad/touch",
            *POSES,
        }
        for hand in (LEFT, RIGHT)
    },
    "/interaction_profiles/oculus/touch_controller": {
        hand: {
            "/input/squeeze/value",
            "/input/trigger/value",
            "/input/trigger/touch",
            "/input/thumbstick/x",
            "/input/thumbstick/y",
            "/input/thumbstick/click",
            "/input/thumbstick/touch",
            "/input/thumbrest/touch",
            *POSES,
            *(
                {
                    "/input/x/click",
                    "/input/x/touch",
                    "/input/y/click",
                    "/input/y/touch",
                    "/input/menu/click",
                }
                if hand == LEFT
                else {"/input/a/click", "/input/a/touch", "/input/b/click", "/input/b/touch"}
            ),
        }
        for hand in (LEFT, RIGHT)
    },
    "/interaction_profiles/valve/index_controller": {
        hand: {
            "/input/system/touch",
            "/input/a/click",
            "/input/a/touch",
            "/input/b/click",
            "/input/b/touch",
            "/input/squeeze/value",
            "/input/squeeze/force",
            "/input/trigger/click",
            "/input/trigger/value",
            "/input/trigger/touch",
            "/input/thumbstick/x",
            "/input/thumbstick/y",
            "/input/thumbstick/click",
            "/input/thumbstick/touch",
            "/input/trackpad/x",
            "/input/trackpad/y",
            "/input/trackpad/force",
            "/input/trackpad/touch",
            *POSES,
        }
        for hand in (LEFT, RIGHT)
    },
}
# Inputs with an axis (a value with a sign): the only ones a region other than ANY makes sense on.
AXES = {"/input/thumbstick/x", "/input/thumbstick/y", "/input/trackpad/x", "/input/trackpad/y"}

# What each profile must offer (the issue: next/previous material, rotate environment,
# exposure up/down, reset); the simple controller has two buttons a hand.
WANTED = {
    Action.NEXT_MATERIAL,
    Action.PREVIOUS_MATERIAL,
    Action.ROTATE_ENVIRONMENT,
    Action.EXPOSURE_UP,
    Action.EXPOSURE_DOWN,
    Action.RESET_VIEW,
}
SIMPLE_CANNOT = {Action.ROTATE_ENVIRONMENT, Action.EXPOSURE_UP, Action.EXPOSURE_DOWN}


def bound(profile: str) -> set[Action]:
    return {
        item.action
        for item in xb.XR_ACTIONS
        if item.action is not None and any(b.profile == profile for b in item.bindings)
    }


def test_the_five_profiles_and_valid_names():
    assert set(xb.PROFILES) == set(SPEC)
    # OpenXR: action and action-set names are well-formed path components (lowercase letters,
    # digits, "-", "_", "."), at most 64 bytes (XR_MAX_ACTION_NAME_SIZE incl. the terminator).
    well_formed = re.compile(r"^[a-z0-9_.-]{1,63}$")
    assert well_formed.match(xb.ACTION_SET)
    names = [item.name for item in xb.XR_ACTIONS]
    assert all(well_formed.match(n) for n in names) and len(set(names)) == len(names)


def test_every_action_maps_to_the_vocabulary_with_blender_values():
    for item in xb.XR_ACTIONS:
        assert item.type in {"FLOAT", "VECTOR2D", "POSE", "VIBRATION"}
        assert item.op_mode in {"PRESS", "RELEASE", "MODAL"}
        assert item.user_paths and set(item.user_paths) <= {LEFT, RIGHT}
        if item.type == "POSE":
            assert item.action is None and item.op == ""
            continue
        assert isinstance(item.action, Action) and item.op == "btf.xr_action"
        # Continuous actions run modal (an event per frame while held), discrete ones once.
        assert (item.op_mode == "MODAL") == (item.action in CONTINUOUS)
        assert item.amount > 0
        for b in item.bindings:
            assert b.axis0_region in {"ANY", "POSITIVE", "NEGATIVE"}
            assert b.axis1_region in {"ANY", "POSITIVE", "NEGATIVE"}
            assert 0.0 < b.threshold < 1.0
    assert xb.for_action(Action.ROTATE_ENVIRONMENT).amount == 45.0  # °/s at full deflection
    assert xb.for_action(Action.EXPOSURE_UP).amount == pytest.approx(1 / 3)  # stops a press


def test_pose_actions_for_blender():
    grip, aim = xb.grip_and_aim()
    for name, component in ((grip, "/input/grip/pose"), (aim, "/input/aim/pose")):
        item = xb.xr_action(name)
        assert item.type == "POSE" and item.user_paths == (LEFT, RIGHT)
        assert {b.profile for b in item.bindings} == set(SPEC)
        assert all(b.component_paths == (component, component) for b in item.bindings)


def test_every_profile_binds_every_action_it_can():
    for profile in SPEC:
        wanted = WANTED - SIMPLE_CANNOT if profile.endswith("khr/simple_controller") else WANTED
        assert bound(profile) == wanted, profile
    assert set(xb.MISSING_ON_SIMPLE) == SIMPLE_CANNOT


def test_component_paths_are_in_the_spec_for_their_hand():
    for item in xb.XR_ACTIONS:
        profiles = [b.profile for b in item.bindings]
        assert len(profiles) == len(set(profiles)), item.name  # one binding per profile
        for b in item.bindings:
            # Blender refuses a binding whose component paths do not pair with the user paths.
            assert len(b.component_paths) == len(item.user_paths), (item.name, b.profile)
            for hand, component in zip(item.user_paths, b.component_paths, strict=True):
                assert component in SPEC[b.profile][hand], (item.name, b.profile, hand)
                if b.axis0_region != "ANY":
                    assert component in AXES
                if item.action is not None:
                    assert component not in POSES
                    # A thumbstick or trackpad axis drives only continuous actions (a press
                    # action on an axis would fire on every brush of the stick).
                    assert (component in AXES) == (item.action in CONTINUOUS), item.name


def test_no_two_actions_share_an_input_of_one_hand():
    used: dict[tuple[str, str, str], list[tuple[str, str]]] = {}
    for item in xb.XR_ACTIONS:
        for b in item.bindings:
            for hand, component in zip(item.user_paths, b.component_paths, strict=True):
                used.setdefault((b.profile, hand, component), []).append(
                    (item.name, b.axis0_region)
                )
    for key, users in used.items():
        for i, (name_a, region_a) in enumerate(users):
            for name_b, region_b in users[i + 1 :]:
                # Regions overlap unless they are the two opposite halves of one axis.
                disjoint = {region_a, region_b} == {"POSITIVE", "NEGATIVE"}
                assert disjoint, f"{name_a} and {name_b} both on {key}"


def test_lookups():
    assert xb.xr_action("next_material").action is Action.NEXT_MATERIAL
    assert xb.xr_action("next_material").user_paths == (RIGHT,)
    assert xb.xr_action("previous_material").user_paths == (LEFT,)
    with pytest.raises(KeyError):
        xb.xr_action("nope")
    with pytest.raises(KeyError):
        xb.for_action(Action.SCREENSHOT)
    assert xb.is_continuous(xb.for_action(Action.ROTATE_ENVIRONMENT))
    assert not xb.is_continuous(xb.for_action(Action.RESET_VIEW))

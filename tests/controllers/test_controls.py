"""The action API: bindings as data and the step function, driven by sample timestamps."""

from __future__ import annotations

import pytest
from wiimote_streams import CALIBRATION_REPLY, STATUS_NO_EXTENSION, records, report_0x37

from btf_addon.controllers.actions import Action
from btf_addon.controllers.bindings import Binding, Kind, default_bindings
from btf_addon.controllers.controls import Controls
from btf_addon.controllers.replay import ReplayTransport
from btf_addon.controllers.transport import ControllerDisconnectedError, ControllerError
from btf_addon.controllers.wiimote.buttons import Button as Btn
from btf_addon.controllers.wiimote.driver import NunchukState, Sample, Wiimote


def s(t: float, *buttons: Btn, tilt=(0.0, 0.0), nunchuk=None) -> Sample:
    mask = 0
    for b in buttons:
        mask |= b
    return Sample(t, mask, tilt_deg=tilt, nunchuk=nunchuk)


def discrete(edits) -> list[tuple[float, Action, float]]:
    return [(e.t, e.action, e.amount) for e in edits if not e.continuous]


def total(edits, action: Action, axis: str = "") -> float:
    return sum(e.amount for e in edits if e.action is action and e.axis == axis)


def test_presses_fire_once_on_the_press_edge():
    edits = Controls().step(
        1.0, [s(0.0), s(0.1, Btn.RIGHT), s(0.2, Btn.RIGHT), s(0.3), s(0.4, Btn.PLUS), s(0.5)]
    )
    assert discrete(edits) == [(0.1, Action.NEXT_MATERIAL, 1.0), (0.4, Action.EXPOSURE_UP, 1 / 3)]


def test_each_default_button_binding():
    cases = {
        Btn.LEFT: Action.PREVIOUS_MATERIAL,
        Btn.UP: Action.LIGHTS_MORE,
        Btn.DOWN: Action.LIGHTS_FEWER,
        Btn.A: Action.NEXT_OBJECT,
        Btn.MINUS: Action.EXPOSURE_DOWN,
        Btn.ONE: Action.PROGRESSIVE_TOGGLE,
        Btn.TWO: Action.SCREENSHOT,
    }
    for button, action in cases.items():
        edits = Controls().step(0.2, [s(0.0), s(0.1, button), s(0.2)])
        assert [e.action for e in edits] == [action], button


def test_environment_rotation_for_a_hold_time():
    # B + Right held from 0.5 s to 2.5 s: 45°/s × 2 s = 90°, one gesture (one undo step).
    samples = [s(0.0)] + [s(0.5 + 0.01 * i, Btn.B, Btn.RIGHT) for i in range(200)]
    samples += [s(2.5, Btn.B), s(2.6)]
    edits = Controls().step(2.6, samples)
    assert total(edits, Action.ROTATE_ENVIRONMENT) == pytest.approx(90.0, abs=1e-9)
    ends = [e for e in edits if e.end]
    assert [(e.t, e.action) for e in ends] == [(2.5, Action.ROTATE_ENVIRONMENT)]
    assert not discrete([e for e in edits if not e.end])  # Right did not step the material
    left = Controls().step(1.0, [s(0.0, Btn.B), s(0.0, Btn.B, Btn.LEFT), s(1.0, Btn.B)])
    assert total(left, Action.ROTATE_ENVIRONMENT) == pytest.approx(-45.0)


def test_dpad_dominance_no_leak_into_the_perpendicular_direction():
    # Right pressed, thumb rolls onto Up as well, then off Right: Up never fires while held.
    samples = [s(0.0), s(0.1, Btn.RIGHT), s(0.2, Btn.RIGHT, Btn.UP), s(0.3, Btn.UP), s(0.4)]
    assert [e.action for e in Controls().step(0.4, samples)] == [Action.NEXT_MATERIAL]
    # A fresh press of Up afterwards counts.
    samples += [s(0.5, Btn.UP)]
    assert [e.action for e in Controls().step(0.5, samples)][-1] is Action.LIGHTS_MORE
    # Both in one report: Left wins by the fixed order, Down is ignored.
    edits = Controls().step(0.2, [s(0.0), s(0.1, Btn.LEFT, Btn.DOWN), s(0.2)])
    assert [e.action for e in edits] == [Action.PREVIOUS_MATERIAL]
    # Environment rotation (B + Right) does not pick up a leaked Left either.
    edits = Controls().step(
        1.0, [s(0.0, Btn.B, Btn.RIGHT), s(0.5, Btn.B, Btn.RIGHT, Btn.LEFT), s(1.0, Btn.B)]
    )
    assert total(edits, Action.ROTATE_ENVIRONMENT) == pytest.approx(45.0)


def test_home_alone_is_help_home_plus_a_is_reset_never_both():
    tap = Controls().step(0.3, [s(0.0), s(0.1, Btn.HOME), s(0.2)])
    assert discrete(tap) == [(0.2, Action.HELP_TOGGLE, 1.0)]  # on release
    combo = Controls().step(
        0.5, [s(0.0), s(0.1, Btn.HOME), s(0.2, Btn.HOME, Btn.A), s(0.3, Btn.HOME), s(0.4)]
    )
    assert discrete(combo) == [(0.2, Action.RESET_VIEW, 1.0)]


def test_tilt_with_b_rotates_the_object_at_90_degrees_per_second_at_full_tilt():
    samples = [s(0.0, Btn.B, tilt=(45.0, 5.0)), s(1.0, Btn.B, tilt=(45.0, 5.0)), s(2.0)]
    edits = Controls().step(2.0, samples)
    assert total(edits, Action.ROTATE_OBJECT, "Z") == pytest.approx(45.0 * 2)  # 90°/s × ½ × 2 s
    assert total(edits, Action.ROTATE_OBJECT, "X") == 0.0  # 5° pitch: inside the dead zone
    assert [e.t for e in edits if e.end] == [2.0]
    without_b = Controls().step(2.0, [s(0.0, tilt=(45.0, 0.0)), s(2.0, tilt=(45.0, 0.0))])
    assert without_b == []


def test_nunchuk_stick_orbits_and_c_z_zoom():
    right = NunchukState(stick=(1.0, 0.0))
    half_up = NunchukState(stick=(0.0, 0.5), c=True)
    samples = [s(0.0, nunchuk=right), s(0.5, nunchuk=half_up), s(1.5, nunchuk=NunchukState())]
    edits = Controls().step(1.5, samples)
    assert total(edits, Action.ORBIT_CAMERA, "YAW") == pytest.approx(30.0)  # 60°/s × 0.5 s
    assert total(edits, Action.ORBIT_CAMERA, "PITCH") == pytest.approx(30.0)  # 60 × ½ × 1 s
    assert total(edits, Action.ZOOM_IN) == pytest.approx(1.0)
    small = NunchukState(stick=(0.1, -0.1))  # inside the 0.15 dead zone
    assert Controls().step(1.0, [s(0.0, nunchuk=small), s(1.0, nunchuk=small)]) == []


def test_step_integrates_up_to_now_and_finish_ends_gestures():
    controls = Controls()
    first = controls.step(1.0, [s(0.0, Btn.B, Btn.RIGHT)])
    assert total(first, Action.ROTATE_ENVIRONMENT) == pytest.approx(45.0)
    second = controls.step(1.5, [s(1.5, Btn.B, Btn.RIGHT)])
    assert total(second, Action.ROTATE_ENVIRONMENT) == pytest.approx(22.5)  # not counted twice
    ended = controls.finish(1.5)
    assert [(e.action, e.end) for e in ended] == [(Action.ROTATE_ENVIRONMENT, True)]


def test_bindings_are_data_and_validated():
    for binding in default_bindings():
        assert Binding.from_dict(binding.to_dict()) == binding
    with pytest.raises(ControllerError):
        Binding(Action.NEXT_MATERIAL, "STICK_X")  # a press needs a button
    with pytest.raises(ControllerError):
        Binding.from_dict({"action": "FLY", "input": "A"})
    custom = Controls([Binding(Action.ZOOM_IN, "A", Kind.HOLD, rate=2.0)])
    edits = custom.step(1.0, [s(0.0, Btn.A), s(0.25)])
    assert total(edits, Action.ZOOM_IN) == pytest.approx(0.5)
    assert default_bindings()[7].describe() == "B + Left (hold)"


@pytest.mark.parametrize(
    ("action", "input_", "kind", "message"),
    [
        # Hold or axis on a discrete action: one discrete edit (an undo step, a toggle) per report.
        (Action.NEXT_MATERIAL, "A", Kind.HOLD, "HOLD binding cannot drive NEXT_MATERIAL"),
        (Action.HELP_TOGGLE, "STICK_X", Kind.AXIS, "AXIS binding cannot drive HELP_TOGGLE"),
        # A press on a continuous action: a gesture that never ends.
        (Action.ZOOM_IN, "C", Kind.PRESS, "PRESS binding cannot drive ZOOM_IN"),
        (Action.ORBIT_CAMERA, "A", Kind.PRESS, "PRESS binding cannot drive ORBIT_CAMERA"),
    ],
)
def test_a_binding_kind_must_fit_its_action(action, input_, kind, message):
    with pytest.raises(ControllerError, match=message):
        Binding(action, input_, kind)
    with pytest.raises(ControllerError, match=message):
        Binding.from_dict({"action": action.name, "input": input_, "kind": kind.name})


def test_every_fitting_kind_is_accepted():
    assert Binding(Action.NEXT_MATERIAL, "A", Kind.PRESS, ("B",)).kind is Kind.PRESS  # a combo
    assert Binding(Action.ROTATE_ENVIRONMENT, "LEFT", Kind.HOLD).kind is Kind.HOLD
    assert Binding(Action.ROTATE_OBJECT, "ROLL", Kind.AXIS, full_scale=90.0).kind is Kind.AXIS


def test_replay_stream_to_edits():
    # The full stack: hand-written reports → replay → driver → controls.
    b_right = "0204"  # Right (0x0200) + B (0x0004)
    stream = records(
        (0.0, STATUS_NO_EXTENSION),
        (0.01, CALIBRATION_REPLY),
        *[(1.0 + 0.01 * i, report_0x37(buttons=b_right)) for i in range(101)],
        (2.01, report_0x37(buttons="0000")),
        (2.10, report_0x37(buttons="1000")),  # Plus
    )
    wiimote = Wiimote(ReplayTransport(stream))
    wiimote.start()
    controls, edits = Controls(), []
    with pytest.raises(ControllerDisconnectedError):
        while True:
            samples = wiimote.poll(max_reports=7)
            edits += controls.step(wiimote.transport.now(), samples)
    edits += controls.step(wiimote.transport.now(), wiimote.pending)
    assert total(edits, Action.ROTATE_ENVIRONMENT) == pytest.approx(45.0 * 1.01)
    assert [e.action for e in edits if not e.continuous] == [Action.EXPOSURE_UP]


def test_help_lines_name_inputs_and_rates():
    from btf_addon.controllers.bindings import help_lines

    lines = dict(help_lines(default_bindings()))
    assert lines["B + Left (hold)"] == "Rotate environment −45 °/s"
    assert lines["Home + A"] == "Reset view"
    assert lines["Plus"] == "Exposure + 0.333 stops"
    assert lines["Stick X"] == "Orbit camera yaw 60 °/s"


def test_edits_carry_the_ir_pointer():
    from btf_addon.controllers.wiimote.ir import Dot

    dots = (Dot(100, 383, None), Dot(300, 383, None))
    pointed = Sample(0.1, Btn.RIGHT, ir_dots=dots)
    edits = Controls().step(0.1, [s(0.0), pointed])
    assert edits[0].action is Action.NEXT_MATERIAL
    assert edits[0].pointer == pytest.approx((1 - 400 / 1023, 1 - 766 / 767))
    assert Controls().step(0.1, [s(0.0), s(0.1, Btn.RIGHT)])[0].pointer is None

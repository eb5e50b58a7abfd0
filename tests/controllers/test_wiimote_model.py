"""The driver and the step function against a scripted Wiimote that answers the driver's own
requests (tests/wiimote_model.py), end to end."""

from __future__ import annotations

from itertools import pairwise

import pytest
from wiimote_model import WiimoteModel

from btf_addon.controllers.actions import Action
from btf_addon.controllers.controls import Controls
from btf_addon.controllers.transport import ControllerDisconnectedError
from btf_addon.controllers.wiimote.driver import WATCHDOG_S, Wiimote


def run(model: WiimoteModel):
    wiimote, controls, edits = Wiimote(model), Controls(), []
    wiimote.start()
    with pytest.raises(ControllerDisconnectedError):
        while True:
            edits += controls.step(model.now(), wiimote.poll(max_reports=1))
    return wiimote, edits


def test_handshake_ir_registers_and_calibration():
    model = WiimoteModel([], end_s=0.5)
    wiimote, _ = run(model)
    assert wiimote.calibrated and wiimote.calibration.one_g == (616, 616, 616)
    # The IR camera's registers as the driver left them (sensitivity 3, basic mode).
    regs = model.registers
    assert regs[0xB00030] == 0x08 and regs[0xB00033] == 0x01
    assert bytes(regs[0xB00000 + i] for i in range(9)).hex() == "020000710100aa0064"
    assert bytes(regs[0xB0001A + i] for i in range(2)).hex() == "6303"
    assert model.mode == 0x37 and model.leds == 0b0001
    assert not [e for e in wiimote.events if e.kind in ("timeout", "error", "unexpected")]


def test_nunchuk_hot_plug_and_stick_orbit_end_to_end():
    stick_right = bytes((0xE0, 0x80))
    model = WiimoteModel(
        [(1.0, "0000", stick_right), (2.0, "0000", None)], end_s=2.5, nunchuk_at_s=0.5
    )
    wiimote, edits = run(model)
    assert wiimote.extension == "nunchuk"
    orbit = sum(e.amount for e in edits if e.action is Action.ORBIT_CAMERA and e.axis == "YAW")
    assert orbit == pytest.approx(60.0, abs=1e-6)  # full right for exactly 1 s of reports


def test_environment_hold_on_the_model():
    model = WiimoteModel([(1.0, "0204", None), (1.5, "0000", None)], end_s=2.0)
    _, edits = run(model)
    total = sum(e.amount for e in edits if e.action is Action.ROTATE_ENVIRONMENT)
    assert total == pytest.approx(22.5, abs=1e-6)


def rotation(edits) -> float:
    return sum(e.amount for e in edits if e.action is Action.ROTATE_ENVIRONMENT)


def test_short_status_report_keeps_data_flowing():
    # Issue 30 item 9: after a truncated 0x20 the model sends no data until the mode is sent
    # again; the driver re-sends it at once, so a hold right after it counts in full.
    model = WiimoteModel(
        [(0.6, "0204", None), (1.1, "0000", None)], end_s=1.5, short_status_at_s=0.5
    )
    wiimote, edits = run(model)
    assert rotation(edits) == pytest.approx(22.5, abs=1e-6)
    assert not [e for e in wiimote.events if e.kind == "watchdog"]


def test_watchdog_restores_data_after_a_lost_status_report():
    # The mode is lost with no report at all: only the watchdog can bring data back.
    model = WiimoteModel([(1.5, "0204", None), (2.0, "0000", None)], end_s=2.5, lose_mode_at_s=0.5)
    wiimote, edits = run(model)
    kicks = [e.t for e in wiimote.events if e.kind == "watchdog"]
    assert len(kicks) == 1 and 0.99 <= kicks[0] <= 1.01  # 0.5 s after the last data (0.49)
    assert model.mode == 0x37
    assert rotation(edits) == pytest.approx(22.5, abs=1e-6)


def test_watchdog_is_bounded_while_the_wiimote_stays_silent():
    model = WiimoteModel([], end_s=3.0, lose_mode_at_s=0.5, deaf_from_s=0.5)
    wiimote, _ = run(model)  # about 250 polls that find nothing
    kicks = [e.t for e in wiimote.events if e.kind == "watchdog"]
    assert 4 <= len(kicks) <= 5
    assert all(b - a >= WATCHDOG_S - 1e-9 for a, b in pairwise(kicks))
    after = [w.hex() for w in model.written if w[0] in (0x12, 0x15)][3:]  # after the start's
    assert after == ["120437", "1500"] * len(kicks)


def test_nunchuk_unplugged_stops_the_orbit_at_the_status_report():
    # Issue 30 item 10: the stick held right until the unplug status report at 1.5 s orbits
    # for exactly 0.5 s, not until the next data report.
    stick_right = bytes((0xE0, 0x80))
    model = WiimoteModel([(1.0, "0000", stick_right)], end_s=2.0, nunchuk_at_s=0.5, unplug_at_s=1.5)
    wiimote, edits = run(model)
    assert wiimote.extension is None
    orbit = sum(e.amount for e in edits if e.action is Action.ORBIT_CAMERA and e.axis == "YAW")
    assert orbit == pytest.approx(30.0, abs=1e-6)

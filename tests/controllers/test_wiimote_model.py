"""The driver and the step function against a scripted Wiimote that answers the driver's own
requests (tests/wiimote_model.py), end to end."""

from __future__ import annotations

import pytest
from wiimote_model import WiimoteModel

from btf_addon.controllers.actions import Action
from btf_addon.controllers.controls import Controls
from btf_addon.controllers.transport import ControllerDisconnectedError
from btf_addon.controllers.wiimote.driver import Wiimote


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

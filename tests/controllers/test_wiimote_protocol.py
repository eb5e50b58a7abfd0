"""The Wiimote's report parsers and builders against bytes from the protocol description."""

from __future__ import annotations

import pytest

from btf_addon.controllers.wiimote import accel, ir, memory, nunchuk, reports
from btf_addon.controllers.wiimote.buttons import Button, button_names, parse_buttons


def h(text: str) -> bytes:
    return bytes.fromhex(text.replace(" ", ""))


def test_buttons_big_endian_and_masked():
    # Byte 0: Left 0x01, Up 0x08, Plus 0x10; byte 1: A 0x08, Home 0x80; 0x60 bits are accel LSBs.
    mask = parse_buttons(h("79 e8"))
    assert mask == Button.LEFT | Button.UP | Button.PLUS | Button.A | Button.HOME
    assert button_names(parse_buttons(h("02 04"))) == {"RIGHT", "B"}
    assert parse_buttons(h("00 00")) == 0


def test_output_reports_byte_for_byte():
    assert reports.leds_report(0b0001) == h("11 10")
    assert reports.leds_report((True, False, False, True)) == h("11 90")
    assert reports.leds_report(0b1111, rumble=True) == h("11 f1")
    assert reports.reporting_mode_report(0x37) == h("12 04 37")
    assert reports.reporting_mode_report(0x31, continuous=False, rumble=True) == h("12 01 31")
    assert reports.status_request_report() == h("15 00")
    assert reports.ir_enable_reports() == (h("13 04"), h("1a 04"))
    with pytest.raises(ValueError):
        reports.reporting_mode_report(0x20)


def test_memory_requests_byte_for_byte():
    assert memory.read_request(0x0016, 8) == h("17 00 00 00 16 00 08")
    assert memory.read_request(0x04A400FA, 6, rumble=True) == h("17 05 a4 00 fa 00 06")
    assert memory.write_request(0x04A400F0, b"\x55") == h("16 04 a4 00 f0 01 55") + bytes(15)
    with pytest.raises(ValueError):
        memory.write_request(0x04B00000, bytes(17))


def test_status_report():
    status = reports.parse_status(h("20 00 08 1a 00 00 64"))  # A held, LED 1, ext, IR, half
    assert status.buttons == Button.A
    assert status.extension and status.ir and not status.battery_low and not status.speaker
    assert status.leds == 0b0001
    assert status.battery == pytest.approx(0x64 / 0xC8)
    with pytest.raises(reports.ReportError):
        reports.parse_status(h("20 00 00 12"))


def test_ack_and_read_reply():
    ack = reports.parse_ack(h("22 00 00 16 03"))
    assert (ack.report, ack.error) == (0x16, 3)
    reply = memory.parse_read_reply(h("21 00 00 50 00 fa 00 00 a4 20 00 00") + bytes(10))
    assert (reply.error, reply.offset, reply.data) == (0, 0x00FA, h("00 00 a4 20 00 00"))
    failed = memory.parse_read_reply(h("21 00 00 08 00 16") + bytes(16))  # error 8
    assert failed.error == 8 and failed.data == b""
    with pytest.raises(ValueError, match="truncated"):
        memory.parse_read_reply(h("21 00 00 f0 00 20 01 02"))  # 16 announced, 2 present


def test_accelerometer_ten_bits():
    # x LSBs = byte 0 bits 6:5 (0x60 → 3); y bit 1 = byte 1 bit 5; z bit 1 = byte 1 bit 6.
    assert accel.parse_accel(h("60 60 80 81 9a")) == (0x200 | 3, 0x204 | 2, 0x268 | 2)
    assert accel.parse_accel(h("00 00 80 81 9a")) == (0x200, 0x204, 0x268)


def test_calibration_and_tilt():
    cal = accel.parse_calibration(h("80 80 80 00 9a 9a 9a 00"))
    assert cal.zero == (512, 512, 512) and cal.one_g == (616, 616, 616)
    low_bits = accel.parse_calibration(h("80 80 80 39 9a 9a 9a 00"))  # 0x39: x 3, y 2, z 1
    assert low_bits.zero == (515, 514, 513)
    assert accel.parse_calibration(h("80 80 80 00 70 9a 9a 00")) is None  # one g below zero
    flat = accel.to_g((512, 512, 616), cal)
    assert flat == pytest.approx((0.0, 0.0, 1.0))
    assert accel.tilt_deg(flat) == pytest.approx((0.0, 0.0))
    rolled = accel.to_g((616, 512, 512), cal)  # gravity along +x: a quarter turn of roll
    assert accel.tilt_deg(rolled) == pytest.approx((90.0, 0.0))
    pitched = accel.to_g((512, 564, 602), cal)  # y = 0.5 g, z = 0.865 g: 30° pitch
    assert accel.tilt_deg(pitched)[1] == pytest.approx(30.0, abs=0.1)  # 10-bit steps ≈ 0.6°


def test_ir_basic_and_extended_dots():
    # Basic: dot 1 (0x123, 0x145), dot 2 (0x367, 0x289); hi byte 0x5b = y1 01 x1 01 y2 10 x2 11.
    dots = ir.parse_basic(h("23 45 5b 67 89 ff ff ff ff ff"))
    assert [(d.x, d.y, d.size) for d in dots] == [(0x123, 0x145, None), (0x367, 0x289, None)]
    # Extended: x 0x223, y 0x145, size 3 (0x63 = y hi 01, x hi 10, size 0011); others absent.
    dots = ir.parse_extended(h("23 45 63") + h("ff ff ff") * 3)
    assert [(d.x, d.y, d.size) for d in dots] == [(0x223, 0x145, 3)]
    assert ir.parse_basic(h("ff") * 10) == []


def test_ir_init_writes_level_3():
    writes = ir.ir_memory_writes(3, ir.MODE_EXTENDED)
    assert writes == [
        h("16 04 b0 00 30 01 08") + bytes(15),
        h("16 04 b0 00 00 09 02 00 00 71 01 00 aa 00 64") + bytes(7),
        h("16 04 b0 00 1a 02 63 03") + bytes(14),
        h("16 04 b0 00 33 01 03") + bytes(15),
    ]
    with pytest.raises(ValueError):
        ir.ir_memory_writes(6, ir.MODE_BASIC)


def test_nunchuk_data_and_calibration():
    data = nunchuk.parse_nunchuk(h("e0 20 80 80 b3 01"))  # stick right/down, C pressed
    assert data.stick_raw == (0xE0, 0x20)
    assert data.c and not data.z
    assert nunchuk.parse_nunchuk(h("80 80 80 80 b3 02")).z
    released = nunchuk.parse_nunchuk(h("80 80 80 80 b3 e7"))  # low bits z 3, y 2, x 1
    assert not released.c and not released.z
    assert released.accel_raw == (0x201, 0x202, 0x2CF)
    cal = nunchuk.parse_nunchuk_calibration(h("80808000 b3b3b300 e02080 e02080 0000"))
    assert cal.stick.x == (0x20, 0x80, 0xE0)
    assert nunchuk.stick_value(0xE0, cal.stick.x) == 1.0
    assert nunchuk.stick_value(0x20, cal.stick.x) == -1.0
    assert nunchuk.stick_value(0xB0, cal.stick.x) == pytest.approx(0.5)
    assert nunchuk.parse_nunchuk_calibration(h("ff") * 16) is None


def test_pointer_from_the_sensor_bar_dots():
    centre = [ir.Dot(411, 383, None), ir.Dot(611, 383, None)]  # midpoint (511, 383)
    assert ir.pointer(centre) == pytest.approx((1 - 1022 / 1023, 1 - 766 / 767))
    left_in_camera = [ir.Dot(100, 0, 2), ir.Dot(300, 0, 3), ir.Dot(900, 700, 1)]
    x, y = ir.pointer(left_in_camera)  # the two largest: (100, 0) and (300, 0)
    assert x == pytest.approx(1 - 400 / 1023) and y == 1.0  # mirrored: points right and up
    assert ir.pointer([ir.Dot(5, 5, None)]) is None

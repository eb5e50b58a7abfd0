"""Report streams written by hand from the protocol description (docs/controllers.md, DESIGN.md
"Controllers and headsets"), never produced by the driver's own encoders. Each report is the hex
a Wiimote sends or must be sent, with its meaning beside it."""

from __future__ import annotations

from btf_addon.controllers.replay import IN, Record


def pad(hex_text: str, length: int) -> str:
    """Zero padding to ``length`` bytes (the Wiimote's fixed report sizes)."""
    raw = hex_text.replace(" ", "")
    return raw + "00" * (length - len(raw) // 2)


# What the driver must write on start (IR on, sensitivity 3), byte for byte.
START_OUTPUT = [
    "11 10",  # LEDs: player LED 1
    "15 00",  # status request
    "13 04",  # IR camera clock on
    "1a 04",  # IR camera enable
    pad("16 04b00030 01 08", 22),  # IR: 0x08 to 0x04B00030
    pad("16 04b00000 09 020000710100aa0064", 22),  # sensitivity block 1, level 3
    pad("16 04b0001a 02 6303", 22),  # sensitivity block 2, level 3
    pad("16 04b00033 01 01", 22),  # IR mode 1 (basic: 10 bytes in 0x37)
    "12 04 37",  # continuous, buttons + accel + IR + extension
    "17 00000016 0008",  # read the accelerometer calibration: 8 bytes at EEPROM 0x0016
]
START_OUTPUT = [h.replace(" ", "") for h in START_OUTPUT]

# The Wiimote's answers.
STATUS_NO_EXTENSION = "20 0000 10 0000 c8"  # LED 1, battery full
STATUS_EXTENSION = "20 0000 12 0000 64"  # LED 1 + extension, battery half
ACK_WRITE = "22 0000 16 00"  # write acknowledged, no error
# Calibration: zero (0x80, 0x80, 0x80), one g (0x9a, 0x9a, 0x9a) → 10-bit 512 and 616.
CALIBRATION_REPLY = pad("21 0000 70 0016 8080 8000 9a9a 9a00", 22)
NUNCHUK_ID_REPLY = pad("21 0000 50 00fa 0000a4200000", 22)
# Nunchuk calibration: accel zero 0x80 ×3, one g 0xb3 ×3, stick x max e0 min 20 centre 80,
# y the same, checksum.
NUNCHUK_CAL_REPLY = "21 0000 f0 0020 80808000 b3b3b300 e02080 e02080 0000"
NUNCHUK_INIT_OUTPUT = [
    pad("16 04a400f0 01 55", 22),
    pad("16 04a400fb 01 00", 22),
    "1704a400fa0006",
]


def report_0x37(
    buttons: str = "0000", accel: str = "80809a", ir: str = "ff" * 10, ext: str = "808080809a03"
) -> str:
    """A 0x37 report: buttons, accel high bytes, 10 basic IR bytes, 6 extension bytes."""
    return "37" + buttons + accel + ir + ext


def records(*timed: tuple[float, str]) -> list[Record]:
    return [Record(t, IN, bytes.fromhex(h.replace(" ", ""))) for t, h in timed]

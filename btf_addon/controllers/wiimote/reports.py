"""Report ids, output reports, the status report (0x20) and acknowledgements (0x22).

Byte offsets in the docstrings count from the first byte after the report id ("payload"), as
WiiBrew does. Bit 0 of every output report's first payload byte is the rumble motor: every
builder takes ``rumble`` so that no report switches it off by accident.
"""

from __future__ import annotations

from dataclasses import dataclass

from .buttons import parse_buttons

# Output reports (host → Wiimote)
LEDS = 0x11
REPORTING_MODE = 0x12
IR_ENABLE = 0x13
STATUS_REQUEST = 0x15
WRITE_MEMORY = 0x16
READ_MEMORY = 0x17
IR_ENABLE_2 = 0x1A

# Input reports (Wiimote → host)
STATUS = 0x20
READ_REPLY = 0x21
ACK = 0x22
DATA_MODES = (0x30, 0x31, 0x32, 0x33, 0x34, 0x35, 0x36, 0x37, 0x3D, 0x3E, 0x3F)

#: Input report id → its length including the id (shorter reports are truncated).
INPUT_LENGTHS = {STATUS: 7, READ_REPLY: 22, ACK: 5, **dict.fromkeys(DATA_MODES, 22)}
INPUT_LENGTHS[0x30] = 3
INPUT_LENGTHS[0x31] = 6
INPUT_LENGTHS[0x32] = 11
INPUT_LENGTHS[0x33] = 18

LED_BITS = (0x10, 0x20, 0x40, 0x80)  # LED 1..4 in the 0x11 payload (and status byte 2)
CONTINUOUS = 0x04  # reporting-mode flag: report at the full rate, not only on change
IR_ON = 0x04  # payload of 0x13 and 0x1a


class ReportError(ValueError):
    """A report that cannot be parsed (truncated); the driver logs and skips it."""


def _rumble(rumble: bool) -> int:
    return 0x01 if rumble else 0x00


def leds_report(leds: tuple[bool, bool, bool, bool] | int, rumble: bool = False) -> bytes:
    """0x11: ``leds`` as four booleans (LED 1..4) or a 4-bit mask (bit 0 = LED 1)."""
    mask = leds if isinstance(leds, int) else sum(1 << i for i, on in enumerate(leds) if on)
    value = sum(bit for i, bit in enumerate(LED_BITS) if mask & (1 << i))
    return bytes((LEDS, value | _rumble(rumble)))


def reporting_mode_report(mode: int, continuous: bool = True, rumble: bool = False) -> bytes:
    """0x12: byte 0 = 0x04 for continuous reporting (| rumble), byte 1 = mode 0x30–0x3f."""
    if mode not in DATA_MODES:
        raise ValueError(f"not a data reporting mode: {mode:#x}")
    return bytes((REPORTING_MODE, (CONTINUOUS if continuous else 0) | _rumble(rumble), mode))


def status_request_report(rumble: bool = False) -> bytes:
    return bytes((STATUS_REQUEST, _rumble(rumble)))


def ir_enable_reports(rumble: bool = False) -> tuple[bytes, bytes]:
    """0x13 and 0x1a with 0x04: the IR camera's clock and its enable line."""
    return (
        bytes((IR_ENABLE, IR_ON | _rumble(rumble))),
        bytes((IR_ENABLE_2, IR_ON | _rumble(rumble))),
    )


@dataclass(frozen=True)
class Status:
    """0x20, payload: 0-1 buttons, 2 flags (0x01 battery low, 0x02 extension, 0x04 speaker,
    0x08 IR, high nibble LEDs), 3-4 zero, 5 battery (0xC8 = full)."""

    buttons: int
    battery_low: bool
    extension: bool
    speaker: bool
    ir: bool
    leds: int  # 4-bit mask, bit 0 = LED 1
    battery: float  # 0..1 (byte 5 / 0xC8, clipped)


def parse_status(report: bytes) -> Status:
    if len(report) < 7 or report[0] != STATUS:
        raise ReportError(f"status report needs 7 bytes, got {len(report)}")
    flags = report[3]
    return Status(
        buttons=parse_buttons(report[1:3]),
        battery_low=bool(flags & 0x01),
        extension=bool(flags & 0x02),
        speaker=bool(flags & 0x04),
        ir=bool(flags & 0x08),
        leds=flags >> 4,
        battery=min(report[6] / 0xC8, 1.0),
    )


@dataclass(frozen=True)
class Ack:
    """0x22, payload: 0-1 buttons, 2 the output report acknowledged, 3 error (0 = success)."""

    buttons: int
    report: int
    error: int


def parse_ack(report: bytes) -> Ack:
    if len(report) < 5 or report[0] != ACK:
        raise ReportError(f"ack report needs 5 bytes, got {len(report)}")
    return Ack(parse_buttons(report[1:3]), report[3], report[4])

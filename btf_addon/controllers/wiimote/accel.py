"""Accelerometer: 10-bit x, y, z and the EEPROM calibration at 0x0016.

Data (payload bytes 2-4 of modes 0x31/0x33/0x35/0x37): the high 8 bits of x, y, z. Low bits
in the button bytes: x bits 1:0 = byte 0 bits 6:5; y bit 1 = byte 1 bit 5; z bit 1 = byte 1
bit 6 (y and z lose their lowest bit).
Calibration (8 bytes at EEPROM 0x0016, read with 0x17): 0-2 zero x, y, z (high 8 bits), 3 their
low bits (x 5:4, y 3:2, z 1:0), 4-6 one-g x, y, z, 7 their low bits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

CALIBRATION_ADDRESS = 0x0016
CALIBRATION_SIZE = 8


@dataclass(frozen=True)
class AccelCalibration:
    zero: tuple[int, int, int]  # 10-bit counts at 0 g
    one_g: tuple[int, int, int]  # 10-bit counts at +1 g

    @classmethod
    def default(cls) -> AccelCalibration:
        # Typical values (0x80 and 0x9A in 8 bits) for when the EEPROM read fails.
        return cls((0x200, 0x200, 0x200), (0x268, 0x268, 0x268))


def parse_accel(payload: bytes) -> tuple[int, int, int]:
    """Payload bytes 0-4 (buttons + 3 accel bytes) → raw 10-bit (x, y, z)."""
    if len(payload) < 5:
        raise ValueError("accelerometer data needs 5 payload bytes")
    b0, b1 = payload[0], payload[1]
    x = (payload[2] << 2) | ((b0 >> 5) & 0x03)
    y = (payload[3] << 2) | ((b1 >> 4) & 0x02)
    z = (payload[4] << 2) | ((b1 >> 5) & 0x02)
    return x, y, z


def parse_calibration(data: bytes) -> AccelCalibration | None:
    """8 bytes from 0x0016 → calibration, None when unusable (one-g not above zero)."""
    if len(data) < CALIBRATION_SIZE:
        return None

    def ten_bits(high: bytes, low: int) -> tuple[int, int, int]:
        return (
            (high[0] << 2) | (low >> 4 & 3),
            (high[1] << 2) | (low >> 2 & 3),
            (high[2] << 2) | (low & 3),
        )

    zero, one = ten_bits(data[0:3], data[3]), ten_bits(data[4:7], data[7])
    if any(g <= z for g, z in zip(one, zero, strict=True)):
        return None
    return AccelCalibration(zero, one)


def to_g(raw: tuple[int, int, int], cal: AccelCalibration) -> tuple[float, float, float]:
    """Raw counts → acceleration in g along the Wiimote's x (right), y (forward), z (up)."""
    return tuple((r - z) / (g - z) for r, z, g in zip(raw, cal.zero, cal.one_g, strict=True))


def tilt_deg(g: tuple[float, float, float]) -> tuple[float, float]:
    """(roll, pitch) in degrees from gravity ``g`` (x, y, z in g): roll = atan2(x, z) (turning
    about the long y axis), pitch = atan2(y, |(x, z)|) (tip up or down); (0, 0) lying flat,
    buttons up. Imprecise while the hand moves: the accelerometer measures motion as well as
    gravity (the thesis's testers said so), hence dead zones in the bindings."""
    x, y, z = g
    roll = math.degrees(math.atan2(x, z)) if (x or z) else 0.0
    pitch = math.degrees(math.atan2(y, math.hypot(x, z))) if (x or y or z) else 0.0
    return roll, pitch

"""The Nunchuk extension: initialisation, identification, calibration and its 6 data bytes.

Init (unencrypted, as current Wiimotes and hid-wiimote do it): write 0x55 to 0x04A400F0, then
0x00 to 0x04A400FB. Identity: 6 bytes at 0x04A400FA, ``00 00 A4 20 00 00`` for a Nunchuk.
Calibration: 16 bytes at 0x04A40020: 0-2 accel zero x, y, z, 3 their low bits, 4-6 accel one-g,
7 their low bits, 8-10 stick x max, min, centre, 11-13 stick y max, min, centre, 14-15 checksum.
Data (6 bytes): 0 stick x, 1 stick y, 2-4 accel x, y, z high bits, 5 = accel low bits (z 7:6,
y 5:4, x 3:2) and the buttons, active low (C = bit 1, Z = bit 0).
"""

from __future__ import annotations

from dataclasses import dataclass

from .accel import AccelCalibration, parse_calibration

INIT_WRITES = ((0x04A400F0, 0x55), (0x04A400FB, 0x00))
ID_ADDRESS = 0x04A400FA
ID_SIZE = 6
CALIBRATION_ADDRESS = 0x04A40020
CALIBRATION_SIZE = 16
NUNCHUK_ID = bytes.fromhex("0000a4200000")
#: Identities the driver knows by name; anything else is reported as "unknown extension".
EXTENSION_NAMES = {
    NUNCHUK_ID: "nunchuk",
    bytes.fromhex("0000a4200101"): "classic",
    bytes.fromhex("0100a4200101"): "classic-pro",
    bytes.fromhex("0000a4200405"): "motion-plus",
}


@dataclass(frozen=True)
class StickCalibration:
    x: tuple[int, int, int]  # (min, centre, max)
    y: tuple[int, int, int]

    @classmethod
    def default(cls) -> StickCalibration:
        # Sticks centre near 128 and reach about ±100 (wiiuse's fallbacks are similar).
        return cls((28, 128, 228), (28, 128, 228))


@dataclass(frozen=True)
class NunchukCalibration:
    accel: AccelCalibration
    stick: StickCalibration

    @classmethod
    def default(cls) -> NunchukCalibration:
        return cls(AccelCalibration.default(), StickCalibration.default())


def parse_nunchuk_calibration(data: bytes) -> NunchukCalibration | None:
    """16 bytes → calibration; None when unusable (all 0x00/0xFF, inverted ranges)."""
    if len(data) < 14 or all(b == 0xFF for b in data) or not any(data):
        return None
    accel = parse_calibration(data[:8]) or AccelCalibration.default()
    x_max, x_min, x_mid, y_max, y_min, y_mid = data[8:14]
    if not (x_min < x_mid < x_max and y_min < y_mid < y_max):
        return NunchukCalibration(accel, StickCalibration.default())
    return NunchukCalibration(accel, StickCalibration((x_min, x_mid, x_max), (y_min, y_mid, y_max)))


@dataclass(frozen=True)
class NunchukData:
    stick_raw: tuple[int, int]
    accel_raw: tuple[int, int, int]  # 10-bit
    c: bool
    z: bool


def parse_nunchuk(data: bytes) -> NunchukData:
    if len(data) < 6:
        raise ValueError("Nunchuk data needs 6 bytes")
    b5 = data[5]
    accel = (
        (data[2] << 2) | ((b5 >> 2) & 3),
        (data[3] << 2) | ((b5 >> 4) & 3),
        (data[4] << 2) | ((b5 >> 6) & 3),
    )
    return NunchukData((data[0], data[1]), accel, c=not b5 & 0x02, z=not b5 & 0x01)


def stick_value(raw: int, cal: tuple[int, int, int]) -> float:
    """A raw stick byte → −1..1 with 0 at the calibrated centre (each half scaled to its end)."""
    low, mid, high = cal
    value = (raw - mid) / (high - mid) if raw >= mid else (raw - mid) / (mid - low)
    return max(-1.0, min(1.0, value))

"""IR camera: initialisation (wiiuse's ``ir.c`` order) and dot decoding.

Initialisation: 0x13 ← 0x04, 0x1a ← 0x04, write 0x08 to register 0x04B00030, sensitivity block
1 (9 bytes) at 0x04B00000, block 2 (2 bytes) at 0x04B0001A, mode at 0x04B00033 (1 basic,
3 extended). Dots: x in 0..1023, y in 0..767; an absent dot reads as all ones.
Basic (10 bytes, 2 dots per 5 bytes): x1, y1 low bytes, then y1 hi (7:6), x1 hi (5:4),
y2 hi (3:2), x2 hi (1:0), then x2, y2 low bytes. Extended (12 bytes, 3 per dot): x, y low bytes,
then y hi (7:6), x hi (5:4), size (3:0).
"""

from __future__ import annotations

from dataclasses import dataclass

from .memory import write_request

REGISTER_BASE = 0x04B00030
BLOCK1_ADDRESS = 0x04B00000
BLOCK2_ADDRESS = 0x04B0001A
MODE_ADDRESS = 0x04B00033
START_VALUE = 0x08
MODE_BASIC = 1
MODE_EXTENDED = 3

#: Sensitivity level → (block 1, block 2), as wiiuse and WiiBrew list them ("Marcan" settings).
SENSITIVITY = {
    1: (bytes.fromhex("0200007101006400fe"), bytes.fromhex("fd05")),
    2: (bytes.fromhex("0200007101009600b4"), bytes.fromhex("b304")),
    3: (bytes.fromhex("020000710100aa0064"), bytes.fromhex("6303")),
    4: (bytes.fromhex("020000710100c80036"), bytes.fromhex("3503")),
    5: (bytes.fromhex("070000710100720020"), bytes.fromhex("1f03")),
}
DEFAULT_SENSITIVITY = 3


@dataclass(frozen=True)
class Dot:
    x: int  # 0..1023
    y: int  # 0..767
    size: int | None  # 0..15 in extended mode, None in basic mode


def ir_memory_writes(level: int, mode: int, rumble: bool = False) -> list[bytes]:
    """The four 0x16 writes after the two enable reports, in order."""
    if level not in SENSITIVITY:
        raise ValueError(f"IR sensitivity level must be 1..5, not {level}")
    if mode not in (MODE_BASIC, MODE_EXTENDED):
        raise ValueError(f"IR mode must be basic (1) or extended (3), not {mode}")
    block1, block2 = SENSITIVITY[level]
    return [
        write_request(REGISTER_BASE, bytes((START_VALUE,)), rumble),
        write_request(BLOCK1_ADDRESS, block1, rumble),
        write_request(BLOCK2_ADDRESS, block2, rumble),
        write_request(MODE_ADDRESS, bytes((mode,)), rumble),
    ]


def _valid(x: int, y: int) -> bool:
    return x != 0x3FF or y != 0x3FF


def parse_basic(data: bytes) -> list[Dot]:
    """10 bytes → up to 4 dots (absent ones left out)."""
    if len(data) < 10:
        raise ValueError("basic IR data needs 10 bytes")
    dots = []
    for base in (0, 5):
        x1, y1, hi, x2, y2 = data[base : base + 5]
        p1 = (x1 | ((hi >> 4) & 3) << 8, y1 | ((hi >> 6) & 3) << 8)
        p2 = (x2 | (hi & 3) << 8, y2 | ((hi >> 2) & 3) << 8)
        dots += [Dot(x, y, None) for x, y in (p1, p2) if _valid(x, y)]
    return dots


def parse_extended(data: bytes) -> list[Dot]:
    """12 bytes → up to 4 dots with sizes (absent ones left out)."""
    if len(data) < 12:
        raise ValueError("extended IR data needs 12 bytes")
    dots = []
    for base in range(0, 12, 3):
        x, y, hi = data[base : base + 3]
        x |= ((hi >> 4) & 3) << 8
        y |= ((hi >> 6) & 3) << 8
        if _valid(x, y):
            dots.append(Dot(x, y, hi & 0x0F))
    return dots


CAMERA_SIZE = (1023, 767)  # the largest x and y a dot can have


def pointer(dots: tuple[Dot, ...] | list[Dot]) -> tuple[float, float] | None:
    """Where the remote points, from the sensor bar's two dots: (x, y) in −1..1, (0, 0) when
    the bar is in the middle of the camera's view, None with fewer than two dots. Uses the two
    largest dots (extended mode) or the first two. x is mirrored (turning the remote right moves
    the bar left in its camera), and y too, assuming the camera's y grows downward in the
    picture as x grows to the camera's right; the y sign is not checked against a device."""
    if len(dots) < 2:
        return None
    two = sorted(dots, key=lambda d: -(d.size or 0))[:2] if dots[0].size is not None else dots[:2]
    mx = (two[0].x + two[1].x) / 2
    my = (two[0].y + two[1].y) / 2
    return 1.0 - 2.0 * mx / CAMERA_SIZE[0], 1.0 - 2.0 * my / CAMERA_SIZE[1]

"""Core buttons: the first two payload bytes of nearly every input report, big-endian."""

from __future__ import annotations

from enum import IntFlag


class Button(IntFlag):
    TWO = 0x0001
    ONE = 0x0002
    B = 0x0004
    A = 0x0008
    MINUS = 0x0010
    HOME = 0x0080
    LEFT = 0x0100
    RIGHT = 0x0200
    DOWN = 0x0400
    UP = 0x0800
    PLUS = 0x1000


BUTTON_MASK = 0x1F9F  # the other bits carry accelerometer low bits (or nothing)


def parse_buttons(two_bytes: bytes) -> int:
    """Payload bytes 0-1 → a ``Button`` bit mask (int)."""
    if len(two_bytes) < 2:
        raise ValueError("buttons need 2 bytes")
    return ((two_bytes[0] << 8) | two_bytes[1]) & BUTTON_MASK


def button_names(mask: int) -> frozenset[str]:
    """A mask → the names of the pressed buttons ("A", "LEFT", ...)."""
    return frozenset(b.name for b in Button if mask & b)

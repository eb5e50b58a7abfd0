"""Memory and register access: write 0x16, read 0x17, read reply 0x21.

0x16 payload: 4-byte big-endian address (0x04 in the first byte selects the register space,
0x00 the EEPROM; bit 0 is rumble), size (1..16), 16 data bytes (zero padded).
0x17 payload: 4-byte address, 2-byte big-endian size.
0x21 payload: 0-1 buttons, 2 = (size − 1) << 4 | error, 3-4 the low 16 bits of the address of
the first byte (big-endian), 5-20 data. Error 0: success, 7: write-only register, 8: no such
address. A read longer than 16 bytes arrives as several replies.
"""

from __future__ import annotations

from dataclasses import dataclass

from .buttons import parse_buttons

WRITE_MEMORY = 0x16
READ_MEMORY = 0x17
READ_REPLY = 0x21
REGISTERS = 0x04000000


def _address_bytes(address: int, rumble: bool) -> bytes:
    if not 0 <= address <= 0xFFFFFFFF:
        raise ValueError(f"address out of range: {address:#x}")
    raw = bytearray(address.to_bytes(4, "big"))
    raw[0] |= 0x01 if rumble else 0x00
    return bytes(raw)


def write_request(address: int, data: bytes, rumble: bool = False) -> bytes:
    """The 22-byte 0x16 report that writes ``data`` (1..16 bytes) at ``address``."""
    if not 1 <= len(data) <= 16:
        raise ValueError(f"a write carries 1..16 bytes, not {len(data)}")
    return (
        bytes((WRITE_MEMORY,))
        + _address_bytes(address, rumble)
        + bytes((len(data),))
        + bytes(data).ljust(16, b"\0")
    )


def read_request(address: int, size: int, rumble: bool = False) -> bytes:
    """The 7-byte 0x17 report that asks for ``size`` bytes from ``address``."""
    if not 1 <= size <= 0xFFFF:
        raise ValueError(f"a read asks for 1..65535 bytes, not {size}")
    return bytes((READ_MEMORY,)) + _address_bytes(address, rumble) + size.to_bytes(2, "big")


@dataclass(frozen=True)
class ReadReply:
    buttons: int
    error: int
    offset: int  # low 16 bits of the address of data[0]
    data: bytes  # ``size`` bytes (empty on error)


def parse_read_reply(report: bytes) -> ReadReply:
    if len(report) < 6 or report[0] != READ_REPLY:
        raise ValueError(f"read reply needs at least 6 bytes, got {len(report)}")
    size = (report[3] >> 4) + 1
    error = report[3] & 0x0F
    offset = (report[4] << 8) | report[5]
    data = b"" if error else bytes(report[6 : 6 + size])
    if not error and len(data) < size:
        raise ValueError(f"read reply truncated: {len(data)} of {size} bytes")
    return ReadReply(parse_buttons(report[1:3]), error, offset, data)

"""The transport interface every controller stream goes through, and the errors users act on.

A transport moves whole HID reports (first byte: the report id) between the driver and a device,
a recording or a scripted device model. The driver never sleeps and never asks the wall clock:
``now()`` is the time of the last report read (a recording's timestamp in a replay, the monotonic
clock on a real device), so the same driver runs in real time and synchronously in tests.
"""

from __future__ import annotations

from typing import Protocol

from ..core.errors import BTFError


class ControllerError(BTFError):
    """A controller cannot be used; the message says why and what to do."""


class NoDeviceError(ControllerError):
    """No Wiimote is connected (or none visible to this process)."""


class DevicePermissionError(ControllerError):
    """A Wiimote exists but its /dev/hidraw* node is not readable and writable by this user."""


class DriverBusyError(ControllerError):
    """The kernel's hid-wiimote driver (or another program) holds the device."""


class ControllerDisconnectedError(ControllerError):
    """The device went away mid-session (or the recording ended)."""


class Transport(Protocol):
    """Whole reports in and out. ``data``/return values: ``bytes`` whose first byte is the
    report id (0x11 LEDs, 0x30 buttons, ...)."""

    def write(self, data: bytes) -> None:
        """Send one output report. Raises ``ControllerDisconnectedError`` when the device is
        gone."""

    def read(self, timeout_s: float) -> bytes | None:
        """The next input report, or None when none arrived within ``timeout_s`` (0: do not
        wait). Raises ``ControllerDisconnectedError`` when the device is gone or a recording
        ended."""

    def now(self) -> float:
        """Seconds: the timestamp of the report the last ``read`` returned (the time of the last
        poll when it returned None)."""

    def close(self) -> None:
        """Release the device or file; further calls raise ``ControllerDisconnectedError``."""

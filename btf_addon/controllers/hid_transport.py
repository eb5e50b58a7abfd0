"""A real Wiimote through hidapi: ``hidraw`` on Linux, ``hid`` on Windows and macOS.

PyPI ``hidapi`` installs two modules. ``hid`` uses libusb on Linux, which cannot see Bluetooth
devices, so Linux uses ``hidraw`` (the kernel's /dev/hidraw* nodes); only the Linux wheel has it,
and the native ``hid`` backends of Windows and macOS see Bluetooth HID. Both are imported inside
functions: the add-on loads without hidapi and says so only when a Wiimote is asked for.
"""

from __future__ import annotations

import errno
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from .transport import (
    ControllerDisconnectedError,
    ControllerError,
    DevicePermissionError,
    DriverBusyError,
    NoDeviceError,
)

VENDOR_ID = 0x057E
PRODUCT_IDS = (0x0306, 0x0330)  # RVL-CNT-01 and the -TR (built-in Motion Plus)
KERNEL_DRIVER = "wiimote"  # the name drivers/hid/hid-wiimote registers under /sys/bus/hid
OUTPUT_REPORT_SIZE = 22  # 0x16 write: id + 21 bytes, the longest output report
REPORT_SIZE = 23  # the longest Wiimote input report (0x3d: id + 21 bytes), with room

UDEV_RULE = (
    'SUBSYSTEM=="hidraw", KERNELS=="0005:057E:0306.*", MODE="0660", TAG+="uaccess"\n'
    'SUBSYSTEM=="hidraw", KERNELS=="0005:057E:0330.*", MODE="0660", TAG+="uaccess"'
)


def hid_module():
    """The hidapi module for this platform, or a ControllerError saying how to get it."""
    name = "hidraw" if sys.platform.startswith("linux") else "hid"
    try:
        return __import__(name)
    except ImportError as exc:
        raise ControllerError(
            f"hidapi's {name!r} module is missing ({exc}): the extension bundles the hidapi "
            "wheel; reinstall the extension, or `pip install hidapi` in Blender's Python"
        ) from exc


@dataclass(frozen=True)
class DeviceInfo:
    path: bytes  # hidapi's path (b"/dev/hidraw3" on Linux)
    product_id: int
    product: str


def find_wiimotes(module=None) -> list[DeviceInfo]:
    """Every Wiimote hidapi enumerates (readable or not: enumeration does not open)."""
    module = module or hid_module()
    found = []
    for pid in PRODUCT_IDS:
        for d in module.enumerate(VENDOR_ID, pid):
            found.append(DeviceInfo(d["path"], pid, d.get("product_string") or "Wiimote"))
    return found


def hidraw_driver(node: str, sys_root: str | Path = "/sys") -> tuple[str | None, str | None]:
    """(driver name, HID device id such as ``0005:057E:0306.0004``) of a /dev/hidrawN node,
    read from sysfs; (None, None) where sysfs does not say."""
    device = Path(sys_root) / "class" / "hidraw" / Path(node).name / "device"
    try:
        hid_id = device.resolve().name
        driver = (device / "driver").resolve().name if (device / "driver").exists() else None
    except OSError:
        return None, None
    return driver, hid_id


def unbind_instructions(hid_id: str) -> str:
    return (
        f"echo -n {hid_id} | sudo tee /sys/bus/hid/drivers/{KERNEL_DRIVER}/unbind && "
        f"echo -n {hid_id} | sudo tee /sys/bus/hid/drivers/hid-generic/bind "
        "(or, for good: `sudo modprobe -r hid-wiimote` and blacklist it)"
    )


def diagnose_open_failure(
    path: bytes | str, exc: BaseException, sys_root="/sys"
) -> ControllerError:
    """Why opening ``path`` failed, as the error a user can act on."""
    node = os.fsdecode(path)
    denied = isinstance(exc, OSError) and exc.errno in (errno.EACCES, errno.EPERM)
    unreadable = os.path.exists(node) and not os.access(node, os.R_OK | os.W_OK)
    if node.startswith("/dev/") and (denied or unreadable):
        return DevicePermissionError(
            f"no permission to open {node} (a Wiimote): add a udev rule, e.g. in "
            f"/etc/udev/rules.d/70-wiimote.rules:\n{UDEV_RULE}\nthen `sudo udevadm control "
            "--reload && sudo udevadm trigger` and reconnect the Wiimote"
        )
    driver, hid_id = hidraw_driver(node, sys_root)
    if driver == KERNEL_DRIVER and hid_id:
        return DriverBusyError(
            f"the kernel driver hid-wiimote holds {node}: unbind it with\n"
            f"{unbind_instructions(hid_id)}"
        )
    return ControllerError(f"could not open the Wiimote at {node}: {exc}")


def check_kernel_driver(path: bytes | str, sys_root="/sys") -> None:
    """Raise DriverBusyError when hid-wiimote is bound: it still exposes /dev/hidrawN, but it
    sets LEDs and reporting modes itself, so raw use would fight it."""
    node = os.fsdecode(path)
    driver, hid_id = hidraw_driver(node, sys_root)
    if driver == KERNEL_DRIVER:
        raise DriverBusyError(
            f"the kernel driver hid-wiimote is bound to {node} and would fight this add-on over "
            f"LEDs and reporting modes: unbind it with\n{unbind_instructions(hid_id or '?')}"
        )


class HidTransport:
    """One opened Wiimote. ``now()`` is ``time.monotonic()`` at the last read."""

    def __init__(self, device, path: bytes, pad_to: int = 0) -> None:
        self._device = device
        self.path = path
        # Windows' HID stack takes output reports only at the device's full output report
        # length (22 bytes for the Wiimote); Linux hidraw takes the report as it is. Not tried
        # on Windows here (no device, no Windows machine).
        self._pad_to = pad_to
        self._now = time.monotonic()
        self._nonblocking = False
        self._closed = False

    def write(self, data: bytes) -> None:
        try:
            written = self._device.write(bytes(data).ljust(self._pad_to, b"\0"))
        except (OSError, ValueError) as exc:
            raise ControllerDisconnectedError(f"the Wiimote went away (write: {exc})") from exc
        if written is not None and written < 0:
            raise ControllerDisconnectedError("the Wiimote went away (write failed)")

    def read(self, timeout_s: float) -> bytes | None:
        try:
            if timeout_s <= 0:
                # hidapi's read with timeout 0 blocks; non-blocking mode returns [] instead.
                if not self._nonblocking:
                    self._device.set_nonblocking(1)
                    self._nonblocking = True
                data = self._device.read(REPORT_SIZE)
            else:
                data = self._device.read(REPORT_SIZE, max(1, int(timeout_s * 1000)))
        except (OSError, ValueError) as exc:
            raise ControllerDisconnectedError(f"the Wiimote went away (read: {exc})") from exc
        self._now = time.monotonic()
        return bytes(data) if data else None

    def now(self) -> float:
        return self._now

    def close(self) -> None:
        """Release the device; a second call does nothing."""
        if not self._closed:
            self._closed = True
            self._device.close()


def open_wiimote(
    index: int = 0, *, record_to: str | Path | None = None, allow_kernel_driver: bool = False
):
    """Open the ``index``-th Wiimote. Raises NoDeviceError, DevicePermissionError,
    DriverBusyError or ControllerError with what to do. ``record_to``: also write the session
    to that JSONL file (see ``replay.py``), for a bug report."""
    module = hid_module()
    devices = find_wiimotes(module)
    if not devices:
        raise NoDeviceError(
            "no Wiimote found: pair it over Bluetooth (press 1 and 2, or the red sync button) "
            "and connect it; on Linux it then shows up as /dev/hidraw*"
        )
    if index >= len(devices):
        raise NoDeviceError(f"Wiimote {index + 1} asked for, {len(devices)} connected")
    info = devices[index]
    if sys.platform.startswith("linux") and not allow_kernel_driver:
        check_kernel_driver(info.path)
    device = module.device()
    try:
        device.open_path(info.path)
    except (OSError, ValueError) as exc:
        raise diagnose_open_failure(info.path, exc) from exc
    transport = HidTransport(
        device, info.path, OUTPUT_REPORT_SIZE if sys.platform == "win32" else 0
    )
    if record_to is not None:
        from .replay import RecordingTransport

        return RecordingTransport(transport, record_to)
    return transport

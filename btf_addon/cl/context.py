"""An OpenCL context on the device chosen by what builds (``devices.choose_device``)."""

from __future__ import annotations

import sys
from dataclasses import dataclass

from .devices import DeviceInfo, OpenCLUnavailableError, choose_device

__all__ = ["CLContext", "OpenCLUnavailableError", "create_context", "install_advice"]


@dataclass
class CLContext:
    context: object
    queue: object
    device: object
    info: DeviceInfo | None = None
    #: Devices tried before this one, each with why it could not build: F12 says so.
    skipped: tuple[tuple[DeviceInfo, str], ...] = ()

    @property
    def device_name(self) -> str:
        return self.info.label if self.info is not None else self.device.name.strip()


def install_advice() -> str:
    """What to install for OpenCL on this platform, in words for a Python prompt or a shell."""
    if sys.platform.startswith("linux"):
        return (
            "Install a GPU's OpenCL driver or a CPU driver registered with the system "
            "(Debian/Ubuntu: sudo apt-get install pocl-opencl-icd; Fedora: sudo dnf install pocl)"
        )
    if sys.platform == "darwin":
        return "macOS provides OpenCL itself; check that nothing blocks the system framework"
    return "Install your GPU vendor's driver (NVIDIA, AMD or Intel): each includes OpenCL"


def create_context(device_index: int | None = None) -> CLContext:
    """A context on device ``device_index`` of ``list_devices()`` where it builds programs, else
    on the first device of ``devices.candidate_order`` that does (GPU, system CPU driver,
    bundled PoCL). Raises OpenCLUnavailableError with each device's reason and what to
    install when none can."""
    import pyopencl as cl

    try:
        choice = choose_device(device_index)
    except OpenCLUnavailableError as exc:  # only discovery and probes: never a kernel's error
        raise OpenCLUnavailableError(exc.reason, install_advice()) from None
    try:
        context = cl.Context([choice.device])
        return CLContext(
            context, cl.CommandQueue(context), choice.device, choice.info, choice.skipped
        )
    except cl.Error as exc:  # probed, but the driver refuses it now (busy, out of memory)
        raise OpenCLUnavailableError(
            f"OpenCL device {choice.info.label} could not be opened ({exc})"
        ) from None

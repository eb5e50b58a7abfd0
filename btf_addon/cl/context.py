"""An OpenCL context on the chosen device."""

from __future__ import annotations

from dataclasses import dataclass

from .devices import OpenCLUnavailableError, best_device_index, list_devices

__all__ = ["CLContext", "OpenCLUnavailableError", "create_context"]


@dataclass
class CLContext:
    context: object
    queue: object
    device: object

    @property
    def device_name(self) -> str:
        return self.device.name.strip()


def create_context(device_index: int | None = None) -> CLContext:
    """Device ``device_index`` of ``list_devices()``, or the best one (GPU, else CPU)."""
    try:
        infos = list_devices()
    except OpenCLUnavailableError as exc:  # only discovery: compile errors are never "no device"
        raise OpenCLUnavailableError(
            f"{exc}. Install a GPU's OpenCL driver or the CPU driver: "
            "pip install pocl-binary-distribution"
        ) from None
    if not infos:
        from . import programs  # an unwritable cache folder is the usual cause: name it

        raise OpenCLUnavailableError(
            f"OpenCL is installed but no device is available{programs.cache_diagnosis()}"
        )
    index = best_device_index(infos) if device_index is None else device_index
    if not 0 <= index < len(infos):
        raise OpenCLUnavailableError(
            f"no OpenCL device {index}; there are {len(infos)} (0–{len(infos) - 1})"
        )
    import pyopencl as cl

    devices = [d for p in cl.get_platforms() for d in _safe_devices(p)]
    device = devices[index]
    try:
        context = cl.Context([device])
        return CLContext(context, cl.CommandQueue(context), device)
    except cl.Error as exc:  # listed, but the driver refuses it (busy, out of memory, broken)
        raise OpenCLUnavailableError(
            f"OpenCL device {device.name.strip()} could not be opened ({exc})"
        ) from None


def _safe_devices(platform):
    import pyopencl as cl

    try:
        return platform.get_devices()
    except cl.Error:
        return []

"""OpenCL platform and device discovery (what the doctor reports and what the renderer picks)."""

from __future__ import annotations

from dataclasses import asdict, dataclass


class OpenCLUnavailableError(RuntimeError):
    """No usable OpenCL device: the message says why and what to install. Only device discovery
    raises it; a kernel that fails to compile is ``programs.OpenCLCompileError`` instead."""


@dataclass(frozen=True)
class DeviceInfo:
    platform: str
    name: str
    type: str  # "GPU", "CPU", "ACCELERATOR" or "OTHER"
    compute_units: int
    global_memory_mb: int
    opencl_version: str

    def to_json(self) -> dict:
        return asdict(self)


def list_devices() -> list[DeviceInfo]:
    """All OpenCL devices of all platforms. Raises OpenCLUnavailableError (a RuntimeError) with a
    readable reason when pyopencl is missing or no platform (ICD) is installed."""
    from . import programs

    programs.prepare_driver_caches()  # an unwritable cache must not look like "no device"
    try:
        import pyopencl as cl
    except ImportError as exc:
        raise OpenCLUnavailableError(f"pyopencl is not installed ({exc})") from None
    try:
        platforms = cl.get_platforms()
    except cl.Error as exc:
        raise OpenCLUnavailableError(
            f"no OpenCL platform found ({exc}){programs.cache_diagnosis()}"
        ) from None
    devices = []
    for platform in platforms:
        try:
            platform_devices = platform.get_devices()
        except cl.Error:
            continue  # a platform with no devices of its own
        for d in platform_devices:
            kind = (
                "GPU"
                if d.type & cl.device_type.GPU
                else "CPU"
                if d.type & cl.device_type.CPU
                else "ACCELERATOR"
                if d.type & cl.device_type.ACCELERATOR
                else "OTHER"
            )
            devices.append(
                DeviceInfo(
                    platform=platform.name.strip(),
                    name=d.name.strip(),
                    type=kind,
                    compute_units=int(d.max_compute_units),
                    global_memory_mb=int(d.global_mem_size // (1024 * 1024)),
                    opencl_version=d.version.strip(),
                )
            )
    return devices


def best_device_index(devices: list[DeviceInfo]) -> int | None:
    """Default choice: the GPU with the most compute units, else the first CPU device."""
    if not devices:
        return None
    ranked = sorted(
        range(len(devices)), key=lambda i: (devices[i].type != "GPU", -devices[i].compute_units)
    )
    return ranked[0]

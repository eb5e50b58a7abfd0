"""OpenCL platform and device discovery, and the choice of device by what builds.

A driver can list a device and still be unable to build any program on it: the PoCL that the
zip bundles (pocl-binary-distribution 3.0, LLVM 14) fails with "unknown target CPU 'generic'"
on CPUs newer than its LLVM (AMD Zen 5 class). So the first time a device is used it builds a
tiny probe program (``probe``); a device that cannot is skipped, with the compiler's reason
kept. The verdict is cached in memory and on disk beside the kernel cache, keyed by platform,
device, driver version and machine (host and CPU), so a new driver or another farm node is
probed again and the same one never twice.

The order devices are tried in (``candidate_order``): the one the user chose, then GPUs (most
compute units first), then CPU drivers registered with the system, then the bundled PoCL.
A device that builds the probe but fails on our kernels is ``programs.OpenCLCompileError``,
not a reason to try the next one: that is a bug to see, not to hide behind another device.
"""

from __future__ import annotations

import functools
import json
import logging
import re
from dataclasses import asdict, dataclass

from ..core.errors import DeviceError
from ..core.fileio import atomic_write

log = logging.getLogger(__name__)


class OpenCLUnavailableError(DeviceError):
    """No usable OpenCL device: the message says why and what to install. Device discovery and
    the probe raise it; a kernel that fails to compile is ``programs.OpenCLCompileError``.
    ``reason`` is the why alone, for callers that give their own advice (Blender's words)."""

    def __init__(self, reason: str, advice: str = ""):
        self.reason, self.advice = reason, advice
        super().__init__(f"{reason}. {advice}" if advice else reason)


#: Builds on any OpenCL 1.2 compiler; it exercises the compiler back end for the device's
#: target (code generation is what fails on an unknown CPU), not only the parser.
PROBE_SOURCE = "__kernel void btf_probe(__global float *x) { x[get_global_id(0)] *= 2.0f; }"


@dataclass(frozen=True)
class DeviceInfo:
    platform: str
    name: str
    type: str  # "GPU", "CPU", "ACCELERATOR" or "OTHER"
    compute_units: int
    global_memory_mb: int
    opencl_version: str
    driver: str = ""  # the platform's own version words, e.g. "PoCL 3.1+debian"
    driver_version: str = ""
    bundled: bool = False  # the PoCL that ships inside the extension (pocl-binary-distribution)

    @property
    def label(self) -> str:
        """What users see: the device and the driver, so two drivers of one CPU differ
        ("pthread-AMD EPYC (PoCL 3.0-rc2, bundled)" beside "… (PoCL 3.1+debian)")."""
        driver = self.driver or self.platform
        return f"{self.name} ({driver}{', bundled' if self.bundled else ''})"

    @property
    def probe_key(self) -> str:
        """Where the verdict holds: this driver and device on this machine. The machine is in
        the key because a device name says little about the CPU under it ("pthread-AMD EPYC"
        is every EPYC generation) and a cache in a shared home folder serves farm nodes of
        several kinds."""
        return "|".join(
            (self.platform, self.driver, self.name, self.driver_version, _machine_identity())
        )

    def to_json(self) -> dict:
        return {**asdict(self), "label": self.label}


@functools.cache
def _machine_identity() -> str:
    """Host name and a digest of the CPU's model and feature flags (Linux; the processor
    string elsewhere): what a compiler's target choice depends on."""
    import hashlib
    import platform

    cpu = ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            cpu = "".join(line for line in fh if line.startswith(("model name", "flags"))).strip()
    except OSError:
        pass
    # Only where /proc says nothing: on Linux processor() forks `uname -p`, a few ms from a
    # process as large as Blender's, on every F12.
    cpu = cpu or platform.processor()
    return f"{platform.node()}:{hashlib.sha256(cpu.encode()).hexdigest()[:12]}"


@dataclass(frozen=True)
class Verdict:
    """Whether a device built the probe program; ``reason`` is the compiler's words when not."""

    builds: bool
    reason: str = ""


def driver_words(platform_version: str, platform_name: str) -> str:
    """The platform version without its "OpenCL 3.0" prefix, cut at the first word that is not
    part of the driver's name and version: "OpenCL 3.0 PoCL 3.1+debian  Linux, …" → "PoCL
    3.1+debian"; "OpenCL 3.0 CUDA 12.4.131" → "CUDA 12.4.131". Falls back to the platform name."""
    words = re.sub(r"^OpenCL\s+\d+(\.\d+)*\s*", "", platform_version.strip()).split()
    kept = []
    for word in words:
        kept.append(word.rstrip(","))
        if any(c.isdigit() for c in word) or word.endswith(","):
            break
    return " ".join(kept[:3]) or platform_name


def _bundled_pocl_version() -> str | None:
    """The version of the PoCL the extension bundles (installed as pocl-binary-distribution
    beside pyopencl), or None where it is not installed (Windows, macOS, a system-only setup)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("pocl-binary-distribution")
    except PackageNotFoundError:
        return None


def _is_bundled(driver: str, bundled_version: str | None) -> bool:
    """PoCL of the bundled version: "PoCL 3.0-rc2" for pocl-binary-distribution 3.0 (its
    library lies in pyopencl/.libs, which OpenCL does not report; the version tells it apart
    from a system PoCL, which distributions ship at their own versions)."""
    if not bundled_version or not driver.startswith("PoCL "):
        return False
    version = driver.removeprefix("PoCL ")
    return version == bundled_version or re.match(re.escape(bundled_version) + r"[-+]", version)


def _platforms():
    """[(platform, [devices])] of every OpenCL platform (pyopencl objects). Raises
    OpenCLUnavailableError with a readable reason when pyopencl or every platform is missing."""
    from . import programs, warm

    programs.prepare_driver_caches()  # an unwritable cache must not look like "no device"
    warm.wait_for_platforms()  # F12 may have started the query on a thread (cl/warm.py)
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
    found = []
    for platform in platforms:
        try:
            found.append((platform, platform.get_devices()))
        except cl.Error:
            continue  # a platform with no devices of its own
    return found


def discover() -> list[tuple[DeviceInfo, object]]:
    """Every device of every platform: its ``DeviceInfo`` beside the pyopencl device. The one
    place that walks the platforms, so indices agree between listing and opening."""
    import pyopencl as cl

    bundled_version = _bundled_pocl_version()
    found = []
    for platform, platform_devices in _platforms():
        driver = driver_words(platform.version, platform.name.strip())
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
            info = DeviceInfo(
                platform=platform.name.strip(),
                name=d.name.strip(),
                type=kind,
                compute_units=int(d.max_compute_units),
                global_memory_mb=int(d.global_mem_size // (1024 * 1024)),
                opencl_version=d.version.strip(),
                driver=driver,
                driver_version=d.driver_version.strip(),
                bundled=bool(_is_bundled(driver, bundled_version)),
            )
            found.append((info, d))
    return found


def list_devices() -> list[DeviceInfo]:
    """All OpenCL devices of all platforms (listed, not yet probed). Raises
    OpenCLUnavailableError with a readable reason when pyopencl or every platform is missing."""
    return [info for info, _ in discover()]


def candidate_order(devices: list[DeviceInfo], chosen: int | None = None) -> list[int]:
    """Indices in the order they are tried: ``chosen`` first, then GPUs (most compute units
    first), then CPU and other drivers registered with the system, then the bundled PoCL;
    discovery order within each group."""

    def rank(i: int):
        d = devices[i]
        return (i != chosen, d.bundled, d.type != "GPU", -d.compute_units * (d.type == "GPU"), i)

    return sorted(range(len(devices)), key=rank)


def best_device_index(devices: list[DeviceInfo]) -> int | None:
    """The first device ``candidate_order`` would try (before probing), or None."""
    order = candidate_order(devices)
    return order[0] if order else None


# -- the probe ----------------------------------------------------------------------------

_verdicts: dict[str, Verdict] = {}


def _verdict_file():
    from . import programs

    return programs.cache_dir() / "device-probes.json"


def _load_disk_verdicts() -> dict[str, Verdict]:
    try:
        data = json.loads(_verdict_file().read_text())
        return {k: Verdict(bool(v["builds"]), str(v.get("reason", ""))) for k, v in data.items()}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return {}  # none yet, or unreadable: probing again is the cure


def _store_verdict(key: str, verdict: Verdict) -> None:
    try:
        table = {k: asdict(v) for k, v in _load_disk_verdicts().items()}
        table[key] = asdict(verdict)
        text = json.dumps(table, indent=1, sort_keys=True)
        atomic_write(_verdict_file(), lambda fh: fh.write(text.encode()))
    except OSError as exc:  # a cache that cannot be written is not an error
        log.info("device probe verdict not cached (%s)", exc)


def build_probe(device) -> Verdict:
    """Build ``PROBE_SOURCE`` on one pyopencl device, in a context of its own."""
    import pyopencl as cl

    try:
        context = cl.Context([device])
    except cl.Error as exc:  # listed, but the driver refuses it (busy, out of memory, broken)
        return Verdict(False, f"the device could not be opened ({exc})")
    program = cl.Program(context, PROBE_SOURCE)
    try:
        program.build(devices=[device])
        return Verdict(True)
    except cl.Error as exc:
        try:
            build_log = program.get_build_info(device, cl.program_build_info.LOG)
        except cl.Error:
            build_log = ""
        return Verdict(False, _first_error(build_log) or _first_error(str(exc)) or str(exc))


def _first_error(text: str) -> str:
    """The compiler's first 'error:' line (the reason in a build log of many lines)."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    errors = [line for line in lines if "error" in line.lower()]
    return (errors or lines or [""])[0][:300]


def probe(info: DeviceInfo, device) -> Verdict:
    """Whether ``device`` builds programs: from memory, else the disk cache, else a real build
    of the probe (a fraction of a second), whose verdict is then cached."""
    key = info.probe_key
    if key not in _verdicts:
        disk = _load_disk_verdicts()
        if key in disk:
            _verdicts[key] = disk[key]
        else:
            verdict = build_probe(device)
            _verdicts[key] = verdict
            _store_verdict(key, verdict)
            if not verdict.builds:
                log.info("OpenCL device %s cannot build programs: %s", info.label, verdict.reason)
    return _verdicts[key]


def forget_verdicts() -> None:
    """Drop the in-memory verdicts (tests; after installing a driver, a restart does the same)."""
    _verdicts.clear()


@dataclass(frozen=True)
class Choice:
    """The device a render will use, and every device tried before it with why it was skipped."""

    index: int
    info: DeviceInfo
    device: object
    skipped: tuple[tuple[DeviceInfo, str], ...] = ()


def choose_device(chosen: int | None = None) -> Choice:
    """The first device of ``candidate_order`` that builds the probe. Raises
    OpenCLUnavailableError naming every device and why it was skipped when none does."""
    found = discover()
    if not found:
        from . import programs  # an unwritable cache folder is the usual cause: name it

        raise OpenCLUnavailableError(
            f"OpenCL is installed but no device is available{programs.cache_diagnosis()}"
        )
    infos = [info for info, _ in found]
    if chosen is not None and not 0 <= chosen < len(found):
        log.warning(
            "no OpenCL device %d (there are %d): choosing automatically", chosen, len(found)
        )
        chosen = None
    skipped = []
    for i in candidate_order(infos, chosen):
        info, device = found[i]
        verdict = probe(info, device)
        if verdict.builds:
            return Choice(i, info, device, tuple(skipped))
        skipped.append((info, verdict.reason))
    reasons = "; ".join(f"{info.label}: {reason}" for info, reason in skipped)
    raise OpenCLUnavailableError(f"no OpenCL device can build programs ({reasons})")


def device_report() -> list[dict]:
    """Every device with its probe verdict and whether it is the one F12 would use (doctor,
    Check System). Raises OpenCLUnavailableError as ``list_devices``."""
    found = discover()
    infos = [info for info, _ in found]
    rows, used = [], None
    for i in candidate_order(infos):
        info, device = found[i]
        verdict = probe(info, device)
        if used is None and verdict.builds:
            used = i
        rows.append((i, info, verdict))
    return [
        {
            "index": i,
            **info.to_json(),
            "builds": verdict.builds,
            **({"reason": verdict.reason} if not verdict.builds else {}),
            "used": i == used,
        }
        for i, info, verdict in sorted(rows, key=lambda row: row[0])
    ]

"""The memory model: how much a command will need at its peak, known before the heavy work.

Each command estimates its peak from its arguments and the headers of its input files
(``Estimate``), and ``require`` refuses it up front with a message naming the size that is too
large, when the estimate exceeds what the process may use (``budget``): the smallest of the
machine's available memory (``MemAvailable``), a cgroup limit, the address-space limit
(``RLIMIT_AS``) less what the process already maps, and a stated limit (``set_limit``, the CLI's
``--max-memory``, or the ``BTF_MEMORY_LIMIT`` environment variable, e.g. ``4G``).

The per-item costs below are measured peaks (``ru_maxrss``, numpy 1.26) rounded up; the
tests in tests/core/test_memory.py run each command under ``RLIMIT_AS`` to check both sides:
a size that fits completes, one that does not is refused with the message.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

from .errors import BTFError

KIB, MIB, GIB = 1 << 10, 1 << 20, 1 << 30

#: What any command needs besides its own arrays: the interpreter, numpy, the code. Measured
#: as ~60 MB resident; address space (RLIMIT_AS) is counted from the process's own size.
BASE_BYTES = 96 * MIB

_stated_limit: int | None = None


class MemoryLimitError(BTFError):
    """The work would need more memory than the process may use: refused before it starts."""


@dataclass(frozen=True)
class Estimate:
    """``peak_bytes`` a piece of work needs at most; ``what`` names it as the user asked for it
    (``swatch --size 8192``) and ``advice`` says how to make it smaller."""

    what: str
    peak_bytes: int
    advice: str = ""

    def __add__(self, other: Estimate) -> Estimate:
        return Estimate(self.what, self.peak_bytes + other.peak_bytes, self.advice or other.advice)


def parse_size(text: str) -> int:
    """``"512M"``, ``"4G"``, ``"1.5GB"``, ``"1000000"`` (bytes) → bytes."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([kKmMgGtT]?)(i?[bB])?\s*", str(text))
    if not m:
        raise BTFError(f"memory size must look like 512M or 4G, got {text!r}")
    scale = {"": 1, "k": KIB, "m": MIB, "g": GIB, "t": 1 << 40}[m.group(2).lower()]
    value = float(m.group(1)) * scale
    if not math.isfinite(value) or value < 1:
        raise BTFError(f"memory size must be positive, got {text!r}")
    return int(value)


def format_size(n: float) -> str:
    for unit, scale in (("GB", GIB), ("MB", MIB), ("kB", KIB)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{int(n)} B"


def set_limit(limit_bytes: int | None) -> None:
    """A stated limit for this process (None: only the machine's own limits)."""
    global _stated_limit
    _stated_limit = limit_bytes


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * KIB
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_available() -> int | None:
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit == "max":
            return None
        used = int(Path("/sys/fs/cgroup/memory.current").read_text())
        return max(int(limit) - used, 0)
    except (OSError, ValueError):
        return None


def _own_address_space() -> int:
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * KIB
    except (OSError, ValueError, IndexError):
        pass
    return 0


def _rlimit_available() -> int | None:
    try:
        import resource
    except ImportError:  # Windows
        return None
    soft, _hard = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    return max(soft - _own_address_space(), 0)


def budget() -> tuple[int | None, str]:
    """(bytes this process may still allocate, where that bound comes from); None when nothing
    is known (then nothing is refused)."""
    candidates = []
    env = os.environ.get("BTF_MEMORY_LIMIT")
    if _stated_limit is not None:
        candidates.append((_stated_limit, "allowed by the stated limit (--max-memory)"))
    elif env:
        candidates.append((parse_size(env), "allowed by the stated limit (BTF_MEMORY_LIMIT)"))
    for value, where in (
        (_meminfo_available(), "available on this machine"),
        (_cgroup_available(), "left under this cgroup's memory limit"),
        (_rlimit_available(), "left under the address-space limit (ulimit -v)"),
    ):
        if value is not None:
            candidates.append((value, where))
    if not candidates:
        return None, "unknown"
    return min(candidates, key=lambda c: c[0])


def require(estimate: Estimate) -> None:
    """Refuse ``estimate`` (``MemoryLimitError``) when it exceeds the budget."""
    limit, where = budget()
    if limit is not None and estimate.peak_bytes > limit:
        advice = f"; {estimate.advice}" if estimate.advice else ""
        raise MemoryLimitError(
            f"{estimate.what} needs about {format_size(estimate.peak_bytes)} of memory at its "
            f"peak, more than the {format_size(limit)} {where}{advice}"
        )


# --- per-command models ------------------------------------------------------------------
# Bytes per item are measured peaks rounded up (see the module docstring).

#: One query row through ``BTF.evaluate_angles``: the (N, 6) float64 copy, directions, the
#: (N, 3) result in float64 and float32. Chunks of core/model.py CHUNK rows bound the rest.
QUERY_ROW_BYTES = 200
#: Working set of one evaluation chunk (2^17 rows, any codec; microgeometry marches 4 points).
EVAL_CHUNK_BYTES = 160 * MIB


#: Peak bytes per byte of a BTFbase ``binary.btf`` (the file, its tables as float32) and of a
#: UBO2014 ``.btf`` (half factors → float32, and the codec's own copy); bounds, with margin,
#: of what the fuzz tests trace (tests/core/test_fuzz_readers.py).
BINARY_BTF_FACTOR = 8
UBO2014_FACTOR = 8


def btf_load(path: str | Path) -> Estimate:
    """Loading a BTF: a BTFbase folder's text tables are parsed whole (bytes, tokens, float64:
    ~12 bytes per byte of the largest file, plus every table as arrays); a .btfm container is
    read whole and viewed (its size, plus one copy a codec may make); ``binary.btf`` and UBO2014
    ``.btf`` files are widened to float32 (their factors above)."""
    path = Path(path)
    if path.is_dir():  # the text tables only: a folder may hold images, reports, archives
        sizes = [p.stat().st_size for p in path.glob("*.txt") if p.is_file()]
        peak = 12 * max(sizes, default=0) + 2 * sum(sizes)
        binary = path / "binary.btf"  # read when the text tables are incomplete
        if binary.is_file():  # its bytes, and its 8-bit tables widened to float32 (4×)
            peak = max(peak, BINARY_BTF_FACTOR * binary.stat().st_size)
    elif path.is_file():
        factor = UBO2014_FACTOR if path.suffix.lower() == ".btf" else 2
        peak = factor * path.stat().st_size
    else:
        peak = 0
    return Estimate(f"loading {path}", peak)


def queries(n_rows: int, what: str) -> Estimate:
    return Estimate(
        what,
        n_rows * QUERY_ROW_BYTES + EVAL_CHUNK_BYTES,
        "split the queries into smaller files",
    )


#: Swatch bands (rows evaluated at once) hold at most this many pixels.
SWATCH_BAND_PIXELS = 1 << 17


def swatch(size: int, suffix: str) -> Estimate:
    """``swatch --size N``: the image is evaluated in bands (SWATCH_BAND_PIXELS at a time) into
    one (N, N, 3) array: float32 for EXR (and the writer's buffers), 8-bit for PNG (its
    filtered rows and their compressed form). Measured at 4096²: 13 B/px EXR, 7 B/px PNG."""
    per_pixel = 24 if suffix == ".exr" else 12
    return Estimate(
        f"swatch --size {size}",
        size * size * per_pixel + EVAL_CHUNK_BYTES,
        "use a smaller --size",
    )


#: ``Environment`` per pixel: the float32 file channels, the float64 radiance, the per-pixel
#: masks, luminance weights, column pdf and cdf (float64 each). Measured: 79 B/px for a
#: 4096 × 2048 map (was ~128 before the map was cleaned in place); the final render's
#: MIS-compensated tables (float32, built later) peak at 56 B/px above the file's own 12.
ENV_PIXEL_BYTES = 96
#: One virtual light while sampling and saving (Sobol points, row/column search, outputs):
#: 10⁶ lights over a 4096-wide map stay below the map's own peak (measured).
LIGHT_BYTES = 400


def environment(width: int, height: int, what: str) -> Estimate:
    return Estimate(what, width * height * ENV_PIXEL_BYTES, "use a smaller environment image")


def virtual_lights(n: int, what: str) -> Estimate:
    return Estimate(what, n * LIGHT_BYTES, "use fewer lights")


def dense_table(n_views: int, n_lights: int, width: int, height: int, what: str) -> Estimate:
    """``tabulate``: the (views, lights, H, W, 3) float32 table, plus one view's queries at a
    time (lights × texels rows of directions and values in float64)."""
    table = n_views * n_lights * width * height * 3 * 4
    per_view = n_lights * width * height * QUERY_ROW_BYTES
    return Estimate(what, table + per_view + EVAL_CHUNK_BYTES, "use a coarser --tabulate grid")


#: Microgeometry per fine sample: height, albedo, normals and their central differences in
#: float64, and the horizon map (32 azimuths, float64) with its temporaries.
MICRO_SAMPLE_BYTES = 600


def microgeometry(fine: int, what: str) -> Estimate:
    return Estimate(what, fine * fine * MICRO_SAMPLE_BYTES, "use fewer --texels")


#: F12 per pixel: Blender's render result (Combined RGBA + Depth + Normal + UV, float32), the
#: renderer's device and host buffers for the same passes, and the image saved through colour
#: management. Measured (demo scene, PNG, PoCL): 74 B/px at 1024², 98 B/px at 2048² above the
#: process's own size; 160 leaves room for the Sampled mode's accumulation and EXR output.
RENDER_PIXEL_BYTES = 160
#: Blender itself (bpy), the add-on and the OpenCL driver before any pixel: 534 MB measured.
RENDER_BASE_BYTES = 768 * MIB


def render(width: int, height: int, n_lights: int, what: str) -> Estimate:
    return Estimate(
        what,
        RENDER_BASE_BYTES + width * height * RENDER_PIXEL_BYTES + n_lights * LIGHT_BYTES,
        "use a smaller --resolution (or render in parts with Blender's border)",
    )

"""BTF commands: info, eval, swatch, synth, convert."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np

from ..core import memory
from ..core.codecs.dense import tabulate
from ..core.codecs.presets import PRESETS, make_preset, preset_parameters
from ..core.errors import BTFError
from ..core.fileio import atomic_write, check_output
from ..core.formats.container import SUFFIX, container_version, write_container
from ..core.formats.imageio import srgb8_from_linear, write_exr, write_png
from ..core.formats.load import bytes_on_disk, load_btf, load_warnings
from ..core.grid import UBO2003, uniform_ring_grid


def add_device_argument(parser) -> None:
    """``--device N``: the OpenCL device, numbered as ``doctor`` lists them."""
    parser.add_argument(
        "--device",
        type=int,
        default=None,
        help="OpenCL device index as listed by `doctor` (default: best GPU, else CPU)",
    )


def add_prefer_binary_argument(parser) -> None:
    """``--prefer-binary``: a BTFbase folder is read from its binary.btf alone."""
    parser.add_argument(
        "--prefer-binary",
        action="store_true",
        help="BTFbase folders: read binary.btf (8-bit, wrapped maxima restored where "
        "possible) instead of the text tables; by default each table comes from its text "
        "file and binary.btf fills only the missing or damaged ones",
    )


def add_parsers(sub) -> None:
    p = sub.add_parser("info", help="describe a BTF (JSON)")
    p.add_argument(
        "path",
        help="BTFbase material folder or binary.btf, UBO2014 .btf, UBO2003/ATRIUM image set "
        "(zip or folder), or .btfm container",
    )
    add_prefer_binary_argument(p)
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("eval", help="evaluate a BTF at queries from a .npy file")
    p.add_argument("path")
    p.add_argument(
        "--queries",
        required=True,
        type=Path,
        help="(N, 6) float32 .npy: u, v, theta_i, phi_i, theta_v, phi_v (degrees)",
    )
    p.add_argument("--out", required=True, type=Path, help="(N, 3) float32 .npy output")
    p.add_argument(
        "--backend",
        choices=["numpy", "opencl"],
        default="numpy",
        help="numpy: the reference; opencl: the device decode kernels of final renders",
    )
    add_device_argument(p)
    p.add_argument(
        "--units",
        choices=["value", "raw"],
        default="value",
        help="value: the project's convention (docs/conventions.md); raw: the codec's "
        "stored units (for MLVQ, the original decoder's 8-bit-scale RGB; for UBO2014, the "
        "file's RGB as stored, without the cosine the convention multiplies in where the "
        "file's cosine flag is 0)",
    )
    p.set_defaults(func=cmd_eval)

    p = sub.add_parser("swatch", help="write the flat sample for one light and view as EXR/PNG")
    p.add_argument("path")
    p.add_argument("--light", nargs=2, type=float, metavar=("THETA", "PHI"), required=True)
    p.add_argument("--view", nargs=2, type=float, metavar=("THETA", "PHI"), required=True)
    p.add_argument("--size", type=int, default=256, help="pixels per side (one texture tile)")
    p.add_argument("-o", "--output", required=True, type=Path, help=".exr (values) or .png")
    p.set_defaults(func=cmd_swatch)

    p = sub.add_parser("synth", help=f"generate a synthetic BTF: {', '.join(PRESETS)}")
    p.add_argument("preset", choices=list(PRESETS))
    p.add_argument("-o", "--output", required=True, type=Path)
    p.add_argument(
        "--tabulate",
        default=None,
        metavar="GRID",
        help="store as a dense table: 'ubo' (81×81) or a ring step in degrees",
    )
    p.set_defaults(func=cmd_synth, accepts_params=True)

    p = sub.add_parser(
        "convert",
        help="any BTF (BTFbase folder or binary.btf, UBO2014 .btf, UBO2003/ATRIUM image set, "
        ".btfm) → .btfm container, or → UBO2014 .btf (svd)",
    )
    p.add_argument("src")
    p.add_argument("dst", type=Path, help=".btfm (default) or .btf (UBO2014 DFMF)")
    p.add_argument(
        "--texels",
        type=int,
        default=None,
        help="image sets: box-filter every image to N×N texels (a full UBO2003 set is 5 GB)",
    )
    p.add_argument(
        "--rank",
        type=int,
        default=None,
        help="store as the svd codec with N components per channel (dense sources; "
        "prints the truncation error); implied (16) for a .btf output",
    )
    add_prefer_binary_argument(p)
    p.set_defaults(func=cmd_convert)


def _container_format(path: Path, btf) -> str:
    form = btf.meta.extra.get("btfbase_form")
    if form:  # a BTFbase folder or binary.btf: which form was read
        return f"btfbase-mlvq-{form}"
    if "file_format" in btf.meta.extra:
        return btf.meta.extra["file_format"]
    return f"btfm-container-v{container_version(path)}"  # 1: raw arrays, 2: compact


def cmd_info(args) -> int:
    path = Path(args.path)
    memory.require(memory.btf_load(path))
    btf = load_btf(path, prefer_binary=args.prefer_binary)
    meta = btf.meta
    on_disk = bytes_on_disk(path, btf)
    info = {
        "path": str(path),
        "format": _container_format(path, btf),
        "codec": meta.codec,
        "name": meta.name,
        "spatial_size": [meta.width, meta.height],
        "angular_grid": meta.angular_grid,
        "views": meta.n_views,
        "lights": meta.n_lights,
        "hdr": meta.hdr,
        # physical size of one tile: null when the source states none (the import asks)
        "tile_size_mm": None if meta.tile_size_mm is None else list(meta.tile_size_mm),
        "tile_size_source": meta.tile_size_source,
        "value_scale": meta.value_scale,
        "bytes_on_disk": on_disk,
        "raw_bytes": meta.raw_bytes,
        "compression_ratio": (meta.raw_bytes / on_disk) if meta.raw_bytes else None,
    }
    if "text_tables_error" in meta.extra:
        info["text_tables_error"] = meta.extra["text_tables_error"]
    tables = meta.extra.get("btfbase_tables", {})
    if "binary" in tables.values():  # which tables binary.btf gave, and what it restored
        info["tables_from_binary"] = [k for k, v in tables.items() if v == "binary"]
        info["binary_recovery"] = meta.extra.get("btfbase_recovery", {})
    if load_warnings(btf):
        info["warnings"] = load_warnings(btf)

    report = path / "quantreport.txt" if path.is_dir() else None
    if report and report.is_file():
        m = re.search(r"compressed quantized = (\d+)\s+ratio = ([\d.]+)", report.read_text())
        if m:
            info["quantised_bytes_reported"] = int(m.group(1))
            info["quantised_ratio_reported"] = float(m.group(2))
    print(json.dumps(info, indent=2))
    return 0


def _save_npy_atomic(path: Path, array: np.ndarray) -> None:
    atomic_write(path, lambda fh: np.save(fh, array))


def load_queries(path: Path, also: memory.Estimate | None = None) -> np.ndarray:
    """A (N, 6) real-valued .npy array, checked from its header before it is read: the
    format, dtype (integers or floats; not complex, bool, object or records), shape, that the
    file holds all N rows, and that N rows fit in memory (core/memory.py)."""
    try:
        with open(path, "rb") as fh:
            magic = fh.read(6)
            if not magic:
                raise BTFError(f"{path}: the file is empty; queries are a (N, 6) .npy array")
            if magic != b"\x93NUMPY":
                fh.seek(0)
                kind = "a .npz archive" if fh.read(2) == b"PK" else "not a .npy file"
                raise BTFError(
                    f"{path}: {kind}; queries must be one array saved with numpy.save (.npy)"
                )
            fh.seek(0)
            version = np.lib.format.read_magic(fh)
            reader = {
                (1, 0): np.lib.format.read_array_header_1_0,
                (2, 0): np.lib.format.read_array_header_2_0,
            }.get(version)
            if reader is None:
                raise BTFError(f"{path}: .npy format version {version} is not supported")
            shape, _fortran, dtype = reader(fh)
            data_start = fh.tell()
    except BTFError:
        raise
    except FileNotFoundError:
        raise BTFError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise BTFError(f"{path}: is a folder, not a .npy file") from None
    except Exception as exc:  # numpy's header parser raises many kinds on a damaged header
        raise BTFError(f"{path}: not a readable .npy array ({type(exc).__name__})") from None
    if dtype.kind not in "iuf" or dtype.fields is not None:
        raise BTFError(
            f"{path}: queries must be real numbers (float or integer), got {dtype}"
            + (" (complex values have no angle meaning)" if dtype.kind == "c" else "")
        )
    if len(shape) != 2 or shape[1] != 6:
        raise BTFError(f"{path}: queries must be a numeric (N, 6) array, got {dtype} {shape}")
    expected = shape[0] * 6 * dtype.itemsize
    if path.stat().st_size - data_start < expected:
        raise BTFError(f"{path}: truncated (the header declares {shape[0]} rows)")
    estimate = memory.queries(shape[0], f"eval of {shape[0]} queries")
    memory.require(estimate if also is None else estimate + also)  # also: the BTF's load
    try:
        q = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise BTFError(f"{path}: not a readable .npy array ({exc})") from None
    # float64, as evaluate_angles reads them; a signalling NaN in a damaged file would raise
    # the FP "invalid" flag in that cast: it is a NaN query like any other (value 0).
    with np.errstate(invalid="ignore"):
        return q.astype(np.float64, copy=False)


def cmd_eval(args) -> int:
    check_output(args.out)  # a folder or an unwritable place: said now, not after the work
    # The cheap checks first (header, shape), then memory for the queries and the BTF together.
    queries = load_queries(args.queries, also=memory.btf_load(args.path))
    btf = load_btf(args.path)
    if args.backend == "opencl":
        from ..cl.context import OpenCLUnavailableError, create_context
        from ..cl.evaluate import device_btf
        from ..cl.programs import OpenCLCompileError

        try:
            btf = device_btf(btf, create_context(args.device))
        except OpenCLUnavailableError as exc:
            raise BTFError(f"OpenCL back end unavailable: {exc}") from None
        except OpenCLCompileError as exc:
            raise BTFError(
                f"OpenCL kernel failed to compile (a bug, please report): {exc}"
            ) from None
    values = btf.evaluate_angles(queries)
    if args.units == "raw":
        values = btf.raw_units(values, queries[:, 2]).astype(np.float32)
    _save_npy_atomic(args.out, values.astype(np.float32))
    return 0


def swatch_image(
    btf, light: tuple[float, float], view: tuple[float, float], size: int, encode=None
):
    """(size, size, 3) values over one tile; row 0 is the top (v = 1), as images are stored:
    float32, or what ``encode`` (a band's values → uint8) makes of them. Evaluated in bands of
    rows (memory.SWATCH_BAND_PIXELS pixels at a time): the peak is the stored image plus one
    band's queries (core/memory.py ``swatch``); every pixel's value is the one a single call
    over the whole tile gives (evaluation is per row)."""
    c = (np.arange(size) + 0.5) / size
    image = np.empty((size, size, 3), dtype=np.float32 if encode is None else np.uint8)
    band = max(1, memory.SWATCH_BAND_PIXELS // size)
    for top in range(0, size, band):
        rows = min(band, size - top)
        u, v = np.meshgrid(c, 1.0 - c[top : top + rows])
        n = rows * size
        q = np.column_stack(
            [
                u.ravel(),
                v.ravel(),
                np.full(n, light[0]),
                np.full(n, light[1]),
                np.full(n, view[0]),
                np.full(n, view[1]),
            ]
        )
        values = btf.evaluate_angles(q).reshape(rows, size, 3)
        image[top : top + rows] = values if encode is None else encode(values)
    return image


def _angle_pair(values, flag: str) -> tuple[float, float]:
    if not all(np.isfinite(values)):
        raise BTFError(f"{flag} must be two finite angles in degrees, got {values}")
    return float(values[0]), float(values[1])


def cmd_swatch(args) -> int:
    if not 1 <= args.size <= 8192:
        raise BTFError(f"--size must be between 1 and 8192, got {args.size}")
    suffix = args.output.suffix.lower()
    if suffix not in (".exr", ".png"):
        raise BTFError(f"{args.output}: output must end in .exr or .png")
    check_output(args.output)
    light, view = _angle_pair(args.light, "--light"), _angle_pair(args.view, "--view")
    memory.require(memory.swatch(args.size, suffix) + memory.btf_load(args.path))
    btf = load_btf(args.path)
    if suffix == ".exr":
        write_exr(args.output, swatch_image(btf, light, view, args.size))
    else:
        # PNG shows reflectance factor (value × π): a white Lambertian lit head-on is 1.0.
        encode = lambda values: srgb8_from_linear(values * np.pi)  # noqa: E731
        write_png(args.output, swatch_image(btf, light, view, args.size, encode))
    return 0


def parse_preset_params(preset: str, tokens: list[str]) -> dict:
    """``--name value`` pairs → typed keyword arguments (types from the preset's defaults)."""
    defaults = preset_parameters(preset)
    params = {}
    it = iter(tokens)
    for token in it:
        if not token.startswith("--"):
            raise BTFError(f"unexpected argument {token!r}; parameters look like --albedo 0.8")
        name = token[2:].replace("-", "_")
        value = next(it, None)
        if value is None:
            raise BTFError(f"parameter --{name} needs a value")
        if name not in defaults:
            raise BTFError(
                f"preset {preset!r} has no parameter --{name}; "
                f"its parameters: {', '.join('--' + k for k in defaults)}"
            )
        default = defaults[name]
        try:
            parts = [float(x) for x in value.split(",")]
        except ValueError:
            raise BTFError(f"--{name}: {value!r} is not a number or comma-separated list") from None
        if not all(np.isfinite(parts)):
            raise BTFError(f"--{name} must be finite, got {value!r}")
        if isinstance(default, int) and not isinstance(default, bool):
            if len(parts) != 1 or parts[0] != int(parts[0]):
                raise BTFError(f"--{name} must be an integer, got {value!r}")
            # Counts (texels, threads, samples per texel) need one; a seed may be 0.
            low = 0 if name == "seed" else 1
            if parts[0] < low:
                raise BTFError(f"--{name} must be at least {low}, got {value!r}")
            params[name] = int(parts[0])
        else:
            params[name] = parts[0] if len(parts) == 1 else tuple(parts)
    return params


#: Finest --tabulate ring step in degrees: below it the grid has > 10⁵ directions per side
#: (a table of 10¹⁰ entries per texel), which no machine holds.
MIN_TABULATE_STEP_DEG = 0.5


def _tabulate_grid(text: str):
    if text == "ubo":
        return UBO2003
    try:
        step = float(text)
    except ValueError:
        raise BTFError(f"--tabulate: 'ubo' or a step in degrees, got {text!r}") from None
    if not (np.isfinite(step) and MIN_TABULATE_STEP_DEG <= step <= 90.0):
        raise BTFError(
            f"--tabulate: a ring step between {MIN_TABULATE_STEP_DEG} and 90 degrees, got {text!r}"
        )
    return uniform_ring_grid(step)


def _preset_estimate(preset: str, params: dict) -> memory.Estimate | None:
    """Microgeometry presets hold (texels × fine_per_texel)² samples in float64 maps."""
    defaults = preset_parameters(preset)
    if "texels" not in defaults or "fine_per_texel" not in defaults:
        return None
    texels = params.get("texels", defaults["texels"])
    fine = texels * params.get("fine_per_texel", defaults["fine_per_texel"])
    return memory.microgeometry(fine, f"synth {preset} with {texels} texels ({fine}² samples)")


def cmd_synth(args) -> int:
    check_output(_with_suffix(args.output))
    params = parse_preset_params(args.preset, args.extra)
    grid = _tabulate_grid(args.tabulate) if args.tabulate else None
    estimate = _preset_estimate(args.preset, params)
    if estimate is not None:
        memory.require(estimate)
    try:
        btf = make_preset(args.preset, **params)
    except ValueError as exc:
        raise BTFError(str(exc)) from None
    if grid is not None:
        w, h = btf.meta.width, btf.meta.height
        table = memory.dense_table(grid.size, grid.size, w, h, f"synth --tabulate {args.tabulate}")
        memory.require(table)
        print(
            f"tabulating {grid.size} views × {grid.size} lights × {w}×{h} texels "
            f"({memory.format_size(grid.size * grid.size * w * h * 12)} of values)",
            file=sys.stderr,
        )
        btf = tabulate(btf, grid, grid)
    write_container(_with_suffix(args.output), btf)
    return 0


def _with_suffix(path: Path) -> Path:
    return path if path.suffix else path.with_suffix(SUFFIX)


def cmd_convert(args) -> int:
    from ..core.codecs.svd_build import factorise
    from ..core.formats.image_sets import is_image_set, load_image_set
    from ..core.formats.ubo2014_writer import write_ubo2014

    check_output(args.dst)
    memory.require(memory.btf_load(args.src))
    src = Path(args.src)
    if args.texels is not None and not 1 <= args.texels <= 4096:
        raise BTFError(f"--texels must be between 1 and 4096, got {args.texels}")
    if src.exists() and is_image_set(src) and not (src / "all_materialInfo.txt").exists():
        btf = load_image_set(src, texels=args.texels)
    else:
        btf = load_btf(src, prefer_binary=args.prefer_binary)
    for warning in load_warnings(btf):  # damaged text, approximate values: said, not hidden
        print(f"warning: {warning}", file=sys.stderr)
    to_btf = args.dst.suffix.lower() == ".btf"
    rank = args.rank if args.rank is not None else (16 if to_btf else None)
    if rank is not None and btf.meta.codec != "svd":
        if btf.meta.codec != "dense":
            raise BTFError(
                f"--rank / .btf output factorises dense (tabulated or image-set) BTFs; this is "
                f"{btf.meta.codec!r}"
            )
        if not 1 <= rank <= 1024:
            raise BTFError(f"--rank must be between 1 and 1024, got {rank}")
        btf, errors = factorise(
            btf.data * np.pi,
            btf.view_grid,
            btf.light_grid,
            ranks=(rank, rank, rank),
            name=btf.meta.name,
        )
        print(json.dumps({"rank": rank, "relative_truncation_error_yuv": errors.tolist()}))
    if to_btf:
        write_ubo2014(args.dst, btf)
    else:
        write_container(_with_suffix(args.dst), btf)
    return 0

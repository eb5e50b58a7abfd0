"""The native BTF container (``.btfm``): one file, any codec, checksummed, written atomically.

Layout (little endian)::

    magic      8 bytes  b"BTFMAT\\r\\n"   (the CR LF catches text-mode transfers)
    version    u32      FORMAT_VERSION (2; version 1 files are read too)
    head_len   u32      length of the JSON header
    header     JSON     {"codec", "params", "meta",
                         "arrays": [{name, dtype, shape, offset, nbytes[, encoding]}]}
    padding    to a 64-byte boundary, then each array's stored bytes at its offset (raw arrays
               64-aligned)
    digest     32 bytes SHA-256 of everything before it (the stored bytes, as on disk)
    end magic  8 bytes  b"BTFEND\\r\\n"

An array without ``encoding`` is its raw bytes (all of version 1). Version 2 stores a table in
the fewest bytes that give it back exactly (``encoding``, see ``_encode``): integer codes of the
smallest width its values need (``base`` + code, or an index into a ``palette`` of the distinct
values — a table quantised to 8 bits has at most 257), optionally differenced along one axis,
then deflated where that pays (zlib, standard library: whole, or byte plane by byte plane).
Reading inflates each once and rebuilds the codec's arrays exactly (same dtype, shape and bits),
so the GPU upload is unchanged.

Why not OpenEXR: MLVQ tables are integer index arrays of many shapes; EXR channels are 2D
half/float/uint images with one size per part, so every table would need reshaping and
integers > 2^24 would need care. A flat, aligned, checksummed container is simpler, exact for
every dtype, and needs only numpy (the core's one dependency). See docs/formats.md.
"""

from __future__ import annotations

import hashlib
import json
import math
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import BTFFormatError, UnsupportedBTFError
from ..fileio import atomic_write
from ..model import BTF

MAGIC = b"BTFMAT\r\n"
END_MAGIC = b"BTFEND\r\n"
FORMAT_VERSION = 2
#: Versions this reader understands (1: raw arrays only).
READ_VERSIONS = (1, 2)
ALIGN = 64
ALLOWED_DTYPES = {"<i4", "<f4", "<f2", "<u1", "<f8"}
SUFFIX = ".btfm"

#: Stored code widths (an encoded array's codes, a palette's entries as bit patterns).
CODE_DTYPES = {"|u1", "<u2", "<u4", "<u8"}
FILTERS = ("none", "delta0", "delta1")
#: none: the codes' bytes; zlib: deflated whole; planes: byte plane by byte plane (all first
#: bytes, then all second bytes, …), each deflated or not.
COMPRESSIONS = ("none", "zlib", "planes")
#: A palette pays for itself only with at most this many distinct values (2-byte codes).
MAX_PALETTE = 1 << 16
#: Arrays above this many bytes get one quick encoding attempt (no filter search, level 6).
SEARCH_LIMIT = 8 << 20
#: Bytes of a large array deflated first to judge whether the whole is worth deflating.
SAMPLE_BYTES = 1 << 20
#: A piece is deflated only when that saves at least this fraction of its bytes (load time:
#: benchmarks/bench_formats.py).
DEFLATE_GAIN = 0.25
#: Floats without a palette are stored deflated only below this fraction of their bytes (a
#: dense table of measured floats deflates by ~30 %, not worth doubling its load time).
BYTES_KEPT = 0.5
#: What inflating a byte at load costs, in stored bytes, when _pack weighs its forms: little
#: in a small table (a load's fixed costs dominate), much in a large one, where inflating runs
#: at a few hundred MB/s against the few GB/s of viewing raw bytes
#: (benchmarks/bench_formats.py, first table).
INFLATE_COST = 0.05
INFLATE_COST_LARGE = 0.5
LARGE_PIECE = 128 << 10
#: A difference filter is kept only when the deflated codes are at most this fraction of the
#: best unfiltered form's.
FILTER_GAIN = 0.9
#: Rebuilt arrays above this many bytes are checked against the memory budget first.
REBUILT_CHECK = 64 << 20
#: Deflate expands at most ~1032×: a piece claiming more than this per stored byte is damaged.
MAX_INFLATE = 1100


def _pad(n: int) -> int:
    return (-n) % ALIGN


def write_container(path: str | Path, btf: BTF, compact: bool = True) -> Path:
    """Write ``btf`` to ``path`` atomically (temp file in the same folder, fsync, rename).

    ``compact`` (default): version 2, each array in the fewest bytes that restore it exactly
    (``_encode``). ``compact=False`` writes version 1 (raw arrays), the format add-ons before
    version 2 read."""
    path = Path(path)
    arrays = {k: np.ascontiguousarray(v) for k, v in btf.tables().items()}
    entries = []
    pieces: list[bytes | np.ndarray] = []
    offset = 0
    for name, a in arrays.items():
        dtype = a.dtype.newbyteorder("<").str if a.dtype.byteorder == ">" else a.dtype.str
        if dtype not in ALLOWED_DTYPES:
            raise ValueError(f"container: array {name!r} has unsupported dtype {a.dtype}")
        a = a.astype(dtype, copy=False)
        # The array's own bytes (a view, not a copy: a table is held once while saved) ...
        stored: list[bytes | np.ndarray] = [a.reshape(-1).view(np.uint8)]
        encoding = None
        if compact:  # ... or its codes (and palette), when they take fewer bytes
            encoded = _encode(a)
            if encoded is not None:
                encoding, stored = encoded
        entry = {"name": name, "dtype": dtype, "shape": list(a.shape)}
        for i, piece in enumerate(stored):
            if encoding is None:  # raw arrays are 64-byte aligned (viewed in place)
                pieces.append(b"\0" * _pad(offset))
                offset += _pad(offset)
            size = len(piece) if isinstance(piece, bytes) else piece.nbytes
            if i == 0:
                entry.update(offset=offset, nbytes=size)
            else:  # the palette: its place in the body
                encoding["palette"].update(offset=offset, nbytes=size)
            pieces.append(piece)
            offset += size
        if encoding is not None:
            entry["encoding"] = encoding
        entries.append(entry)
    header = json.dumps(
        {
            "codec": btf.meta.codec,
            "params": btf.params(),
            "meta": btf.meta.to_json(),
            "arrays": entries,
        },
        sort_keys=True,
        separators=(",", ":") if compact else None,
    ).encode()
    version = FORMAT_VERSION if compact else 1
    prefix = MAGIC + struct.pack("<II", version, len(header)) + header
    prefix += b"\0" * _pad(len(prefix))

    def write(fh) -> None:
        digest = hashlib.sha256()
        for chunk in [prefix, *pieces]:
            fh.write(chunk)
            digest.update(chunk)
        fh.write(digest.digest() + END_MAGIC)

    return atomic_write(path, write)


def _encode(a: np.ndarray) -> tuple[dict, list[bytes]] | None:
    """The smallest exact stored form of ``a`` (little endian, contiguous), or None when the
    raw bytes are as small: (encoding, [codes piece] or [codes piece, palette piece]).

    Integers: ``code = value − min`` in the narrowest unsigned width. Floats with at most
    MAX_PALETTE distinct bit patterns: the index into their sorted patterns (the palette,
    itself stored differenced); others: their own bytes. Each piece then takes the filter
    (none, difference along axis 0 or along the last axis, wrapping in the code width) and
    deflation (none, whole, per byte plane) of ``_pack``."""
    if a.size < 16 or a.ndim == 0:
        return None
    big = a.nbytes > SEARCH_LIMIT
    if a.dtype.kind in "iu":
        low = int(a.min())
        codes = (a.astype(np.int64) - low).astype(_width(int(a.max()) - low))
        encoding: dict[str, Any] = {"kind": "offset", "base": low}
        palette = None
    else:
        bits = a.view(f"<u{a.dtype.itemsize}")
        unique, inverse = None, None
        probe = bits.reshape(-1)[:: max(1, bits.size >> 16)]  # ~65 k values across it
        if probe.size == bits.size or len(np.unique(probe)) <= MAX_PALETTE // 2:
            unique, inverse = np.unique(bits, return_inverse=True)
        if unique is not None and len(unique) <= MAX_PALETTE and len(unique) < a.size // 2:
            codes = inverse.reshape(a.shape).astype(_width(len(unique) - 1))
            palette = unique.astype(unique.dtype.newbyteorder("<"))
            encoding = {"kind": "palette"}
        else:
            codes, palette = bits, None
            encoding = {"kind": "bytes"}
    # floats kept as their own bytes must at least halve to be deflated at all
    gain = 1.0 - BYTES_KEPT if encoding["kind"] == "bytes" else DEFLATE_GAIN
    encoding.update(_pack(codes, big, gain=gain))
    stored = [encoding.pop("data")]
    total = len(stored[0])
    if palette is not None:
        piece = _pack(palette, big, filters=("delta0",))
        stored.append(piece.pop("data"))
        total += len(stored[1])
        encoding["palette"] = {"count": len(palette), **piece}
    # Not worth a rebuild at every load (raw arrays are viewed in place): floats kept as
    # their own bytes must at least halve, anything else save a twentieth.
    if total >= a.nbytes * (BYTES_KEPT if encoding["kind"] == "bytes" else 0.95):
        return None
    return encoding, stored


def _width(largest: int) -> np.dtype:
    for dtype in ("|u1", "<u2", "<u4"):
        if largest <= np.iinfo(np.dtype(dtype)).max:
            return np.dtype(dtype)
    return np.dtype("<u8")


def _pack(
    codes: np.ndarray,
    big: bool,
    filters: tuple[str, ...] = FILTERS,
    gain: float = DEFLATE_GAIN,
) -> dict[str, Any]:
    """The codes' stored form: {"codes", "size", "filter", "compression"[, "planes"],
    "data"}. Deflated only where that saves at least DEFLATE_GAIN of the bytes — the whole
    codes, or (codes wider than a byte) each byte plane on its own, so that the random low
    bytes of 11-bit indices stay as they are and only their high bytes are inflated at load.
    Of the forms, the one of fewest bytes counting each inflated byte as INFLATE_COST (or
    INFLATE_COST_LARGE) wins; a difference filter must beat the unfiltered forms by
    FILTER_GAIN (it is a pass more at every load)."""
    plain = codes.reshape(-1).view(np.uint8).tobytes()
    best: dict[str, Any] = {
        "codes": codes.dtype.str,
        "size": codes.nbytes,
        "filter": "none",
        "compression": "none",
        "data": plain,
    }
    best_score = float(len(plain))
    for filt in ("none",) if big else sorted(filters, key=lambda f: f != "none"):
        shaped = np.ascontiguousarray(_filter(codes, filt))
        forms = []
        whole = _deflate(shaped.reshape(-1).view(np.uint8).tobytes(), big, gain)
        if whole is not None:
            forms.append(({"compression": "zlib", "data": whole}, shaped.nbytes))
        if codes.dtype.itemsize > 1:
            planes = shaped.reshape(-1).view(np.uint8).reshape(-1, codes.dtype.itemsize).T
            stored, inflated = [], 0
            for plane in planes:
                raw = plane.tobytes()
                deflated = _deflate(raw, big, gain)
                stored.append(raw if deflated is None else deflated)
                inflated += 0 if deflated is None else len(raw)
            if inflated:
                form = {"compression": "planes", "planes": [len(p) for p in stored]}
                forms.append(({**form, "data": b"".join(stored)}, inflated))
        for form, inflated in forms:
            cost = INFLATE_COST_LARGE if inflated > LARGE_PIECE else INFLATE_COST
            score = len(form["data"]) + cost * inflated
            if filt != "none" and score > FILTER_GAIN * best_score:
                continue
            if score < best_score:
                best = {"codes": codes.dtype.str, "size": codes.nbytes, "filter": filt, **form}
                best_score = score
    return best


def _deflate(raw: bytes, big: bool, gain: float) -> bytes | None:
    """``raw`` deflated, or None when that does not save ``gain`` of it (a large piece is
    judged by a megabyte of it first)."""
    limit = 1.0 - gain
    if big:
        sample = raw[: SAMPLE_BYTES // 2] + raw[len(raw) // 2 :][: SAMPLE_BYTES // 2]
        if len(zlib.compress(sample, 6)) > limit * len(sample):
            return None
    data = zlib.compress(raw, 6 if big else 9)
    return data if len(data) <= limit * len(raw) else None


def _filter(codes: np.ndarray, name: str) -> np.ndarray:
    if name == "none" or codes.ndim == 0:
        return codes
    axis = 0 if name == "delta0" or codes.ndim == 1 else codes.ndim - 1
    # Differences wrap in the code width; the reader's cumulative sum wraps back.
    return np.diff(codes, axis=axis, prepend=np.zeros_like(np.take(codes, [0], axis=axis)))


def _unfilter(codes: np.ndarray, name: str) -> np.ndarray:
    if name == "none" or codes.ndim == 0:
        return codes
    axis = 0 if name == "delta0" or codes.ndim == 1 else codes.ndim - 1
    return np.cumsum(codes, axis=axis, dtype=codes.dtype)


def container_version(path: str | Path) -> int | None:
    """The format version a ``.btfm`` file states (None: not a container)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(MAGIC) + 4)
    except OSError:
        return None
    if len(head) < len(MAGIC) + 4 or head[: len(MAGIC)] != MAGIC:
        return None
    return struct.unpack_from("<I", head, len(MAGIC))[0]


def read_header(path: str | Path) -> tuple[dict[str, Any], bytes]:
    """Validate the whole file (magic, version, checksum, array bounds) → (header, body)."""
    path = Path(path)
    try:
        blob = path.read_bytes()
    except OSError as exc:
        raise BTFFormatError(f"{path}: cannot read ({exc.strerror})") from None
    fixed = len(MAGIC) + 8
    if len(blob) < fixed + 40 or blob[: len(MAGIC)] != MAGIC:
        raise BTFFormatError(f"{path}: not a BTF container (bad magic or too short)")
    if blob[-len(END_MAGIC) :] != END_MAGIC:
        raise BTFFormatError(f"{path}: truncated (end marker missing)")
    version, head_len = struct.unpack_from("<II", blob, len(MAGIC))
    if version not in READ_VERSIONS:
        raise UnsupportedBTFError(
            f"{path}: container format version {version}; this add-on reads versions "
            f"{READ_VERSIONS[0]} to {READ_VERSIONS[-1]} — update the add-on"
        )
    body_end = len(blob) - len(END_MAGIC) - 32
    if hashlib.sha256(blob[:body_end]).digest() != blob[body_end : body_end + 32]:
        raise BTFFormatError(f"{path}: checksum mismatch (file corrupt)")
    if fixed + head_len > body_end:
        raise BTFFormatError(f"{path}: header length {head_len} runs past the end of the file")
    try:
        header = json.loads(blob[fixed : fixed + head_len])
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):
        raise BTFFormatError(f"{path}: header is not valid JSON") from None
    try:
        # The array entries hold integers and names only (validate_header checks each): the
        # walk looks at the rest, where a float may be a NaN.
        if isinstance(header, dict):
            field = _non_finite_field({k: v for k, v in header.items() if k != "arrays"})
        else:
            field = _non_finite_field(header)
    except RecursionError:
        raise BTFFormatError(f"{path}: header is nested too deeply") from None
    if field is not None:  # NaN / Infinity: json accepts them, a BTF parameter must not
        name, value = field
        raise BTFFormatError(f"{path}: header field {name} is {value}: it must be a finite number")
    data_start = fixed + head_len + _pad(fixed + head_len)
    body = blob[data_start:body_end]
    validate_header(header, len(body), path, version)
    return header, body


def _non_finite_field(value, name: str = "") -> tuple[str, float] | None:
    """The first non-finite number in a parsed JSON value and where it is (``params.scale[2]``),
    or None."""
    if isinstance(value, float) and not math.isfinite(value):
        return name or "(the header)", value
    items = (
        (((f"{name}.{k}" if name else str(k)), v) for k, v in value.items())
        if isinstance(value, dict)
        else ((f"{name}[{i}]", v) for i, v in enumerate(value))
        if isinstance(value, list)
        else ()
    )
    for child_name, child in items:
        found = _non_finite_field(child, child_name)
        if found is not None:
            return found
    return None


#: Dimensions an array may have: the codecs' tables have at most 5 (dense: V, L, H, W, 3).
MAX_NDIM = 8

#: Per codec, each parameter's type and least value, checked before any table is built (the
#: container is checksummed, so these catch files written wrong, not damaged in transit).
PARAM_RULES: dict[str, dict[str, tuple[type, float | None]]] = {
    "mlvq": {
        "n_beta": (int, 3),
        "n_alpha": (int, 3),
        "n_theta": (int, 2),
        "n_phi": (int, 1),
        "use_cos_beta": (bool, None),
        "rows_offset": (int, None),
        "cols_offset": (int, None),
        "hdr_value": (float, 0.0),
        "n_views": (int, 0),
        "n_lights": (int, 0),
        "name": (str, None),
    },
    # Scalars of the analytic codecs (their colours are lists the codec itself checks).
    "ggx": {"roughness": (float, 0.0)},
    "principled": {
        "roughness": (float, 0.0),
        "metallic": (float, 0.0),
        "diffuse_roughness": (float, 0.0),
        "specular_f0": (float, 0.0),
    },
}


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def validate_header(header: Any, body_len: int, path: Path, version: int = FORMAT_VERSION) -> None:
    """Every field's type and range, before any array is allocated or viewed: a header that is
    not an object, missing or mistyped keys, array entries with negative, non-integer or
    overflowing shapes (counted in Python integers), bytes that do not match the shape, arrays
    outside the body, and codec parameters of the wrong type or below their least value."""
    if not isinstance(header, dict):
        raise BTFFormatError(f"{path}: header must be a JSON object, got {type(header).__name__}")
    for key, kind in (("codec", str), ("params", dict), ("meta", dict), ("arrays", list)):
        if key not in header:
            raise BTFFormatError(f"{path}: header has no {key!r}")
        if not isinstance(header[key], kind):
            raise BTFFormatError(
                f"{path}: header {key!r} must be a {kind.__name__}, "
                f"got {type(header[key]).__name__}"
            )
    names = set()
    for i, e in enumerate(header["arrays"]):
        where = f"{path}: array entry {i}"
        if not isinstance(e, dict):
            raise BTFFormatError(f"{where} must be an object")
        for key in ("name", "dtype", "shape", "offset", "nbytes"):
            if key not in e:
                raise BTFFormatError(f"{where} has no {key!r}")
        name = e["name"]
        if not isinstance(name, str) or name in names:
            raise BTFFormatError(f"{where}: name {name!r} is not a string or is repeated")
        names.add(name)
        where = f"{path}: array {name!r}"
        if not isinstance(e["dtype"], str) or e["dtype"] not in ALLOWED_DTYPES:
            raise BTFFormatError(f"{where}: dtype {e['dtype']!r} is not one of {ALLOWED_DTYPES}")
        shape = e["shape"]
        if (
            not isinstance(shape, list)
            or len(shape) > MAX_NDIM
            or not all(_is_int(n) and n >= 0 for n in shape)
        ):
            raise BTFFormatError(
                f"{where}: shape {shape!r} must be a list of at most {MAX_NDIM} integers ≥ 0"
            )
        for key in ("offset", "nbytes"):
            if not _is_int(e[key]) or e[key] < 0:
                raise BTFFormatError(f"{where}: {key} {e[key]!r} must be an integer ≥ 0")
        count = 1
        for n in shape:  # Python integers: a product that overflows int64 is still exact
            count *= n
        if e["offset"] + e["nbytes"] > body_len:
            raise BTFFormatError(f"{path}: array {name!r} lies outside the file")
        if "encoding" in e:
            if version < 2:
                raise BTFFormatError(f"{where}: an encoded array in a version {version} file")
            _validate_encoding(e, count, body_len, where)
        elif count * np.dtype(e["dtype"]).itemsize != e["nbytes"]:
            raise BTFFormatError(
                f"{where}: shape {shape} of {e['dtype']} is not its {e['nbytes']} bytes"
            )
    for key, (kind, least) in PARAM_RULES.get(header["codec"], {}).items():
        value = header["params"].get(key)
        ok = (
            _is_int(value)
            if kind is int
            else isinstance(value, bool)
            if kind is bool
            else isinstance(value, (int, float)) and not isinstance(value, bool)
            if kind is float
            else isinstance(value, kind)
        )
        if not ok:
            raise BTFFormatError(
                f"{path}: parameter {key!r} must be {kind.__name__}, got {value!r}"
            )
        if least is not None and value < least:
            raise BTFFormatError(f"{path}: parameter {key!r} must be ≥ {least}, got {value!r}")


def _validate_piece(spec: Any, size_of: int, where: str) -> None:
    """A stored piece's fields: codes width, decoded size, filter, compression (and planes)."""
    if not isinstance(spec, dict):
        raise BTFFormatError(f"{where}: encoding must be an object")
    for key, kind in (("codes", str), ("size", int), ("filter", str), ("compression", str)):
        if not isinstance(spec.get(key), kind) or isinstance(spec.get(key), bool):
            raise BTFFormatError(f"{where}: encoding {key!r} is missing or not a {kind.__name__}")
    if spec["codes"] not in CODE_DTYPES:
        raise BTFFormatError(f"{where}: code type {spec['codes']!r} is not one of {CODE_DTYPES}")
    if spec["filter"] not in FILTERS or spec["compression"] not in COMPRESSIONS:
        raise BTFFormatError(f"{where}: unknown filter or compression in {spec!r}"[:300])
    if spec["size"] != size_of * np.dtype(spec["codes"]).itemsize:
        raise BTFFormatError(f"{where}: {spec['size']} bytes of codes for {size_of} values")
    if spec["compression"] == "planes":
        planes = spec.get("planes")
        width = np.dtype(spec["codes"]).itemsize
        if (
            not isinstance(planes, list)
            or len(planes) != width
            or width < 2
            or not all(_is_int(n) and n >= 0 for n in planes)
        ):
            raise BTFFormatError(f"{where}: 'planes' must list {width} byte counts (≥ 0)")


def _validate_encoding(e: dict, count: int, body_len: int, where: str) -> None:
    """An encoded array (version 2): its codes and, for a palette, the palette piece; every
    size checked against the shape and the body before anything is inflated."""
    enc = e["encoding"]
    _validate_piece(enc, count, where)
    kind, dtype = enc.get("kind"), np.dtype(e["dtype"])
    if kind == "offset":
        if dtype.kind not in "iu" or not _is_int(enc.get("base")):
            raise BTFFormatError(f"{where}: an offset encoding needs integers and a 'base'")
    elif kind == "bytes":
        if np.dtype(enc["codes"]).itemsize != dtype.itemsize:
            raise BTFFormatError(f"{where}: stored bytes of another width than {dtype}")
    elif kind == "palette":
        pal = enc.get("palette")
        if not isinstance(pal, dict):
            raise BTFFormatError(f"{where}: a palette encoding needs a 'palette' object")
        for key in ("count", "offset", "nbytes"):
            if not _is_int(pal.get(key)) or pal[key] < 0:
                raise BTFFormatError(f"{where}: palette {key!r} must be an integer ≥ 0")
        _validate_piece(pal, pal["count"], where)
        if pal["codes"] != f"<u{dtype.itemsize}" and pal["codes"] != f"|u{dtype.itemsize}":
            raise BTFFormatError(f"{where}: palette entries are not {dtype}'s bit patterns")
        if pal["offset"] + pal["nbytes"] > body_len:
            raise BTFFormatError(f"{where}: the palette lies outside the file")
        _check_inflate(pal, pal["nbytes"], where)
    else:
        raise BTFFormatError(f"{where}: unknown encoding kind {kind!r}"[:200])
    _check_inflate(enc, e["nbytes"], where)


def _check_inflate(spec: dict, stored: int, where: str) -> None:
    """The stored bytes can hold the codes: as many when raw, at most MAX_INFLATE times fewer
    when deflated (a decompression bomb's header is refused before inflating)."""
    size = spec["size"]
    if spec["compression"] == "none" and size != stored:
        raise BTFFormatError(f"{where}: {stored} stored bytes for {size} bytes of codes")
    if spec["compression"] == "zlib" and size > MAX_INFLATE * stored + 64:
        raise BTFFormatError(f"{where}: {stored} deflated bytes cannot hold {size} bytes of codes")
    if spec["compression"] == "planes":
        count = size // np.dtype(spec["codes"]).itemsize
        if sum(spec["planes"]) != stored:
            raise BTFFormatError(f"{where}: the byte planes do not add up to {stored} bytes")
        if any(n != count and count > MAX_INFLATE * n + 64 for n in spec["planes"]):
            raise BTFFormatError(f"{where}: a deflated byte plane cannot hold {count} bytes")


def _inflate(body: bytes, spec: dict, offset: int, nbytes: int, shape, where: str) -> np.ndarray:
    """A stored piece → its codes, (shape) of spec's code type, filters undone."""
    data = memoryview(body)[offset : offset + nbytes]
    dtype = np.dtype(spec["codes"])
    if spec["compression"] == "planes":  # byte planes → values, plane by plane
        count = spec["size"] // dtype.itemsize
        interleaved = np.empty((count, dtype.itemsize), np.uint8)  # little endian: byte i
        start = 0
        for i, stored in enumerate(spec["planes"]):
            piece = data[start : start + stored]
            start += stored
            plane = piece if stored == count else _inflate_bytes(piece, count, where)
            interleaved[:, i] = np.frombuffer(plane, np.uint8)
        codes = interleaved.view(dtype).reshape(count)
    else:
        raw = _inflate_bytes(data, spec["size"], where) if spec["compression"] == "zlib" else data
        codes = np.frombuffer(raw, dtype)
    return _unfilter(codes.reshape(shape), spec["filter"])


def _inflate_bytes(data, size: int, where: str) -> bytes:
    inflater = zlib.decompressobj()
    try:
        raw = inflater.decompress(data, size)
    except zlib.error as exc:
        raise BTFFormatError(f"{where}: the deflated codes are damaged ({exc})") from None
    if len(raw) != size or not inflater.eof or inflater.unconsumed_tail:
        raise BTFFormatError(f"{where}: the codes do not inflate to {size} bytes")
    return raw


def _decode(body: bytes, e: dict, where: str) -> np.ndarray:
    """One array entry → the codec's array: a view of the body (raw) or rebuilt (encoded)."""
    dtype = np.dtype(e["dtype"])
    if "encoding" not in e:
        return np.frombuffer(
            body, dtype=dtype, count=e["nbytes"] // dtype.itemsize, offset=e["offset"]
        ).reshape(e["shape"])
    enc = e["encoding"]
    codes = _inflate(body, enc, e["offset"], e["nbytes"], e["shape"], where)
    if enc["kind"] == "bytes":
        return codes.view(dtype)
    if enc["kind"] == "offset":
        info = np.iinfo(dtype)
        low = enc["base"]
        high = low + int(np.iinfo(codes.dtype).max)  # what the code width allows ...
        if high > info.max and codes.size:
            high = low + int(codes.max())  # ... or, when that does not fit, what is there
        if low < info.min or high > info.max:
            raise BTFFormatError(f"{where}: values from {low} to {high} do not fit {dtype}")
        if codes.dtype.itemsize >= dtype.itemsize:  # codes as wide as the type: go wider
            return (codes.astype(np.int64) + low).astype(dtype)
        values = codes.astype(dtype)
        if low:
            values += dtype.type(low)
        return values
    pal = enc["palette"]
    palette = _inflate(body, pal, pal["offset"], pal["nbytes"], (pal["count"],), where)
    palette = palette.view(dtype)
    try:
        return palette[codes]
    except IndexError:
        raise BTFFormatError(f"{where}: a code beyond its {len(palette)} values") from None


def read_container(path: str | Path) -> BTF:
    header, body = read_header(path)
    encoded = [e for e in header["arrays"] if "encoding" in e]
    rebuilt = sum(2 * np.dtype(e["dtype"]).itemsize * math.prod(e["shape"]) for e in encoded)
    if rebuilt > REBUILT_CHECK:  # the rebuilt arrays are not in the file's size: count them
        from .. import memory

        memory.require(memory.Estimate(f"loading {path}", len(body) + rebuilt))
    arrays = {e["name"]: _decode(body, e, f"{path}: array {e['name']!r}") for e in header["arrays"]}
    from .load import codec_class  # here: codecs imports this module for saving

    try:
        return codec_class(header["codec"]).from_params(header["params"], arrays)
    except (BTFFormatError, UnsupportedBTFError) as exc:  # codecs name the material: add the file
        message = str(exc)
        if str(path) in message:
            raise
        raise type(exc)(f"{path}: {message}") from None
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise BTFFormatError(f"{path}: inconsistent {header.get('codec')} data ({exc})") from None

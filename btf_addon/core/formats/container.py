"""The native BTF container (``.btfm``): one file, any codec, checksummed, written atomically.

Layout (little endian)::

    magic      8 bytes  b"BTFMAT\\r\\n"   (the CR LF catches text-mode transfers)
    version    u32      FORMAT_VERSION
    head_len   u32      length of the JSON header
    header     JSON     {"codec", "params", "meta",
                         "arrays": [{name, dtype, shape, offset, nbytes}]}
    padding    to a 64-byte boundary, then each array's raw bytes at its offset (64-aligned)
    digest     32 bytes SHA-256 of everything before it
    end magic  8 bytes  b"BTFEND\\r\\n"

Why not OpenEXR: MLVQ tables are integer index arrays of many shapes; EXR channels are 2D
half/float/uint images with one size per part, so every table would need reshaping and
integers > 2^24 would need care. A flat, aligned, checksummed container is simpler, exact for
every dtype, memory-mappable, and needs only numpy (the core's one dependency). See
docs/formats.md.
"""

from __future__ import annotations

import hashlib
import json
import math
import struct
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import BTFFormatError, UnsupportedBTFError
from ..fileio import atomic_write
from ..model import BTF

MAGIC = b"BTFMAT\r\n"
END_MAGIC = b"BTFEND\r\n"
FORMAT_VERSION = 1
ALIGN = 64
ALLOWED_DTYPES = {"<i4", "<f4", "<f2", "<u1", "<f8"}
SUFFIX = ".btfm"


def _pad(n: int) -> int:
    return (-n) % ALIGN


def write_container(path: str | Path, btf: BTF) -> Path:
    """Write ``btf`` to ``path`` atomically (temp file in the same folder, fsync, rename)."""
    path = Path(path)
    arrays = {k: np.ascontiguousarray(v) for k, v in btf.tables().items()}
    entries = []
    offset = 0
    for name, a in arrays.items():
        dtype = a.dtype.newbyteorder("<").str if a.dtype.byteorder == ">" else a.dtype.str
        if dtype not in ALLOWED_DTYPES:
            raise ValueError(f"container: array {name!r} has unsupported dtype {a.dtype}")
        entries.append(
            {
                "name": name,
                "dtype": dtype,
                "shape": list(a.shape),
                "offset": offset,
                "nbytes": a.nbytes,
            }
        )
        offset += a.nbytes + _pad(a.nbytes)
    header = json.dumps(
        {
            "codec": btf.meta.codec,
            "params": btf.params(),
            "meta": btf.meta.to_json(),
            "arrays": entries,
        },
        sort_keys=True,
    ).encode()
    prefix = MAGIC + struct.pack("<II", FORMAT_VERSION, len(header)) + header
    prefix += b"\0" * _pad(len(prefix))

    def write(fh) -> None:
        digest = hashlib.sha256()
        for chunk in [prefix] + [
            piece
            for a in arrays.values()
            for piece in (
                # The array's own bytes (a view, not a copy: a table is held once while saved).
                np.ascontiguousarray(a.astype(a.dtype.newbyteorder("<"), copy=False))
                .reshape(-1)
                .view(np.uint8),
                b"\0" * _pad(a.nbytes),
            )
        ]:
            fh.write(chunk)
            digest.update(chunk)
        fh.write(digest.digest() + END_MAGIC)

    return atomic_write(path, write)


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
    if version != FORMAT_VERSION:
        raise UnsupportedBTFError(
            f"{path}: container format version {version}; this add-on reads version "
            f"{FORMAT_VERSION} — update the add-on"
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
        field = _non_finite_field(header)
    except RecursionError:
        raise BTFFormatError(f"{path}: header is nested too deeply") from None
    if field is not None:  # NaN / Infinity: json accepts them, a BTF parameter must not
        name, value = field
        raise BTFFormatError(f"{path}: header field {name} is {value}: it must be a finite number")
    data_start = fixed + head_len + _pad(fixed + head_len)
    body = blob[data_start:body_end]
    validate_header(header, len(body), path)
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


def validate_header(header: Any, body_len: int, path: Path) -> None:
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
        if count * np.dtype(e["dtype"]).itemsize != e["nbytes"]:
            raise BTFFormatError(
                f"{where}: shape {shape} of {e['dtype']} is not its {e['nbytes']} bytes"
            )
        if e["offset"] + e["nbytes"] > body_len:
            raise BTFFormatError(f"{path}: array {name!r} lies outside the file")
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


def read_container(path: str | Path) -> BTF:
    header, body = read_header(path)
    arrays = {
        e["name"]: np.frombuffer(
            body,
            dtype=e["dtype"],
            count=e["nbytes"] // np.dtype(e["dtype"]).itemsize,
            offset=e["offset"],
        ).reshape(e["shape"])
        for e in header["arrays"]
    }
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

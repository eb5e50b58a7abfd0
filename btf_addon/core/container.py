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
import struct
from pathlib import Path
from typing import Any

import numpy as np

from .errors import BTFFormatError, UnsupportedBTFError
from .fileio import atomic_write
from .model import BTF

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
                a.astype(a.dtype.newbyteorder("<"), copy=False).tobytes(),
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
    try:
        header = json.loads(blob[fixed : fixed + head_len])
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise BTFFormatError(f"{path}: header is not valid JSON") from None
    data_start = fixed + head_len + _pad(fixed + head_len)
    body = blob[data_start:body_end]
    for e in header.get("arrays", []):
        count = int(np.prod(e["shape"])) if e["shape"] else 1
        if (
            e["dtype"] not in ALLOWED_DTYPES
            or e["offset"] < 0
            or (
                e["offset"] + e["nbytes"] > len(body)
                or count * np.dtype(e["dtype"]).itemsize != e["nbytes"]
            )
        ):
            raise BTFFormatError(f"{path}: array {e.get('name')!r} lies outside the file")
    return header, body


def read_container(path: str | Path) -> BTF:
    header, body = read_header(path)
    arrays = {
        e["name"]: np.frombuffer(
            body, dtype=e["dtype"], count=int(np.prod(e["shape"])), offset=e["offset"]
        ).reshape(e["shape"])
        for e in header["arrays"]
    }
    from .codecs import codec_class  # here: codecs imports this module for saving

    try:
        return codec_class(header["codec"]).from_params(header["params"], arrays)
    except (KeyError, TypeError, ValueError) as exc:
        raise BTFFormatError(f"{path}: inconsistent {header.get('codec')} data ({exc})") from None

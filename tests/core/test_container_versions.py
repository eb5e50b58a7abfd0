"""The compact .btfm (version 2, issue 31): every table stored in the fewest bytes that give
it back exactly, each damaged encoding refused by name, and version 1 files still read."""

from __future__ import annotations

import base64
import hashlib
import json
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from helpers import random_hemisphere, shared_material

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.errors import BTFFormatError
from btf_addon.core.formats import container
from btf_addon.core.formats.load import load_btf
from btf_addon.core.grid import uniform_ring_grid

#: .btfm files written by the version 1 writer (commit 4db2367, before issue 31), deflated
#: and base64-encoded: a Lambertian (albedo 0.8, 0.5, 0.2) and a Lambertian (0.6, 0.4, 0.3)
#: tabulated on 45° ring grids (a dense codec table).
VERSION_1_FILES = {
    "lambertian": (
        "eNqdkMFOAjEQhtebwXDxrEnTixdCWNDEECOBqCfxxMUQshl2u2xjdxfbAq6wb8Ez+BzGCzGRR/Al9GBIPNhZ0EiM"
        "Huxh2q+df+afNlpnzXorn9uwLOvZhDEFKSFRtEraY+rppM/MkR75+7RAaARhhiC6zIuzm26iGWbbZUOx7yumDZUM"
        "qAAycbvSSTuG3dhjLqoFhF0mNYcIK4RMg7k1jaPeQIB0epJ7WZMIRKK5S3/XshstM3FqIPCkOfogFENivBegFRtd"
        "OgJJrZxFzpCz0RethlovLWHkfM6GWZoL5ih+y5wwxKHsUtFcY+ysvap4IF323X+VDCLuxzIsEIgSgllExPGVIjpg"
        "RGF3U2EIYmDULggU21icjrinAyQcrw8SQrX8qeX3Gxel4mGBlIoHGMqdv22mqfVzzZ/Oa2armf3Y+sfaW8wru7DT"
        "qr+9v17mXpqz7fu76XSyeT3ZepgtZo+N1tnpxUk+9wFWwauQ"
    ),
    "dense": (
        "eNrtkLFLHEEUxjeWB/4Pw1YKR3DJ6cmRHFETIUVsPLBYluXd7tvbIbO7OjPnuZEDbUUQLW39A2ytbLSyCDFN0gZS"
        "prULJO8NMRAIQQypkmHYmW9n3m++7y32ll8u9CYbDzzP25/wvG0ftIba+B0RbvuprdeRtv7jrOU3hV9C4WQKFpzu"
        "1xb57uz8PMkqywxakjMkTA6uNmw3Bc3AzUfROKKzpEoxcSAsDTKpQCJ2BD1fDoYKdDzQMuUbWpYDIzYljkRbbAkl"
        "B7kVbf+XENyy2lHGJPJU0zYDZZAVciH9CNh27DBsvO0k43+o7xkVFH3UVkIppiz0yZTFdJqf0TCKb4MHLa6xUmFs"
        "5GuMi4IjBzMPqQX8jX46NdVQJ44OJajayqQjhqXMKl00BZS14FtCVdUrI2yOwrAXImyCGlJ1AoqLA4b7I5nanBWH"
        "XQcNhXENdNFu2xeGzklr1jkJKfxcFN0p5F+PRC3/rcvx2LvDuD5c6s7BRPf68OLJxxeN7m7/jNa9P9r/Z/6bTO8e"
        "4+Bm7c3O0aenG7aawtWLm90PV5/h+PIkPj1/+/X9l3eLveXnK88mG98A73Lfdw=="
    ),
}


def _fixture(tmp_path: Path, name: str) -> Path:
    path = tmp_path / f"{name}.btfm"
    path.write_bytes(zlib.decompress(base64.b64decode("".join(VERSION_1_FILES[name]))))
    return path


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("lambertian", lambda: LambertianBTF((0.8, 0.5, 0.2))),
        (
            "dense",
            lambda: tabulate(
                LambertianBTF((0.6, 0.4, 0.3)), uniform_ring_grid(45.0), uniform_ring_grid(45.0)
            ),
        ),
    ],
)
def test_version_1_files_from_the_old_writer_still_load(tmp_path, rng, name, expected):
    path = _fixture(tmp_path, name)
    assert container.container_version(path) == 1
    back, want = load_btf(path), expected()
    for key, table in want.tables().items():
        np.testing.assert_array_equal(back.tables()[key], table)
    uv, wi, wo = rng.random((50, 2)), random_hemisphere(rng, 50), random_hemisphere(rng, 50)
    np.testing.assert_array_equal(back.evaluate(uv, wi, wo), want.evaluate(uv, wi, wo))


def test_the_version_1_writer_path_and_version_2_agree(tmp_path):
    alu = MLVQBTF.from_directory(shared_material("alu"))
    v1 = container.write_container(tmp_path / "v1.btfm", alu, compact=False)
    v2 = container.write_container(tmp_path / "v2.btfm", alu)
    assert container.container_version(v1) == 1 and container.container_version(v2) == 2
    assert v2.stat().st_size * 3 < v1.stat().st_size
    one, two = load_btf(v1), load_btf(v2)
    for key, table in alu.tables().items():
        for back in (one, two):
            assert back.tables()[key].dtype == table.dtype
            np.testing.assert_array_equal(back.tables()[key], table)


# --- every encoding, on tables written here ------------------------------------------------
@dataclass
class _Meta:
    codec: str = "stub"
    extra: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"codec": self.codec}


class _Stub:
    """What write_container reads of a BTF: tables, params, meta."""

    def __init__(self, tables: dict[str, np.ndarray]):
        self._tables = tables
        self.meta = _Meta()

    def tables(self) -> dict[str, np.ndarray]:
        return self._tables

    def params(self) -> dict:
        return {}


def _arrays(path: Path) -> tuple[dict, dict[str, np.ndarray]]:
    header, body = container.read_header(path)
    return header, {e["name"]: container._decode(body, e, str(path)) for e in header["arrays"]}


def test_each_kind_of_table_comes_back_bit_for_bit(tmp_path, rng):
    levels = np.float32(0.25) + np.arange(257, dtype=np.float32) * np.float32(0.01)
    tables = {
        "indices": rng.integers(-5, 3000, (400, 11)).astype(np.int32),  # offset, 2-byte codes
        "smooth": np.cumsum(rng.integers(0, 3, (300, 16)), axis=1).astype(np.int32),
        "constant": np.full((64, 4), 7, np.int32),
        "quantised": levels[rng.integers(0, 257, (500, 7))],  # 257 levels: a palette
        "signed_zero": np.array([0.0, -0.0] * 40, np.float32),  # distinct bit patterns
        "float64": np.repeat(rng.random(10), 20).reshape(20, 10),
        "half": rng.random((64, 8)).astype(np.float16),
        "noise": rng.random((128, 9)).astype(np.float32),  # incompressible: raw
        "ramp": np.arange(70_000, dtype=np.float32).reshape(700, 100),  # > 65536 values
        "nan": np.array([np.nan, 1.0, np.inf, -np.inf] * 8, np.float32),
        "tiny": np.array([1, 2, 3], np.int32),
        "empty": np.zeros((0, 3), np.int32),
    }
    path = container.write_container(tmp_path / "s.btfm", _Stub(tables))
    header, back = _arrays(path)
    kinds = {e["name"]: e.get("encoding", {}).get("kind", "raw") for e in header["arrays"]}
    assert kinds["indices"] == "offset" and kinds["quantised"] == "palette"
    assert kinds["noise"] == "raw" and kinds["tiny"] == "raw"
    for name, table in tables.items():
        got = back[name]
        assert got.dtype == table.dtype and got.shape == table.shape, name
        assert got.tobytes() == table.tobytes(), name  # the bits, NaN and -0.0 included


def test_the_checksum_covers_the_stored_bytes(tmp_path):
    path = container.write_container(
        tmp_path / "m.btfm", MLVQBTF.from_directory(shared_material("alu"))
    )
    blob = path.read_bytes()
    assert hashlib.sha256(blob[:-40]).digest() == blob[-40:-8]
    damaged = bytearray(blob)
    damaged[len(blob) // 2] ^= 1
    path.write_bytes(bytes(damaged))
    with pytest.raises(BTFFormatError, match="checksum"):
        load_btf(path)


# --- damaged encodings behind a valid checksum ---------------------------------------------
def _rewrite(path: Path, edit_header=None, edit_body=None) -> None:
    blob = path.read_bytes()
    fixed = len(container.MAGIC) + 8
    version, head_len = struct.unpack_from("<II", blob, len(container.MAGIC))
    header = json.loads(blob[fixed : fixed + head_len])
    start = fixed + head_len + (-(fixed + head_len)) % container.ALIGN
    body = bytearray(blob[start : len(blob) - 40])
    if edit_header:
        edit_header(header)
    if edit_body:
        edit_body(header, body)
    text = json.dumps(header).encode()
    prefix = container.MAGIC + struct.pack("<II", version, len(text)) + text
    prefix += b"\0" * ((-len(prefix)) % container.ALIGN)
    data = prefix + bytes(body)
    path.write_bytes(data + hashlib.sha256(data).digest() + container.END_MAGIC)


def _entry(header: dict, name: str) -> dict:
    return next(e for e in header["arrays"] if e["name"] == name)


def _set(name, key, value):
    return lambda h: _entry(h, name)["encoding"].__setitem__(key, value)


def _palette(name, key, value):
    return lambda h: _entry(h, name)["encoding"]["palette"].__setitem__(key, value)


def _huge(name):
    """2^24 rows claimed for the same few deflated bytes (a decompression bomb's header)."""

    def edit(h):
        e = _entry(h, name)
        e["shape"] = [1 << 24, e["shape"][1]]
        e["encoding"]["size"] = (1 << 24) * e["shape"][1] * 2

    return edit


def _planes_off_by_one(h):
    enc = next(e["encoding"] for e in h["arrays"] if e.get("encoding", {}).get("planes"))
    enc["planes"][0] += 1


def _narrow_palette(h):
    pal = _entry(h, "pdf6_scale")["encoding"]["palette"]
    pal["codes"], pal["size"] = "|u1", pal["count"]


def _flip_deflated(h, body):
    """A byte in the middle of the largest wholly deflated table."""
    deflated = [e for e in h["arrays"] if e.get("encoding", {}).get("compression") == "zlib"]
    e = max(deflated, key=lambda e: e["nbytes"])
    body[e["offset"] + e["nbytes"] // 2] ^= 0xFF


def _codes_beyond_palette(h, body):
    e = _entry(h, "pdf6_scale")
    e["encoding"]["palette"]["count"] = 3  # the codes reach far beyond 3 entries
    pal = e["encoding"]["palette"]
    pal["size"] = 3 * 4
    pal.update(compression="none", filter="none", nbytes=12)


HEADER_CASES = {
    "unknown filter": (_set("pdf2_indices", "filter", "paeth"), None),
    "unknown encoding kind": (_set("pdf2_slices", "kind", "lz4"), None),
    "code type": (_set("pdf2_slices", "codes", "<i8"), None),
    "bytes of codes for": (_set("pdf2_slices", "size", 12), None),
    "cannot hold": (_huge("pdf2_slices"), None),
    "byte counts": (_set("pdf2_slices", "planes", [1, 2, 3]), None),
    "add up": (_planes_off_by_one, None),
    "do not fit": (_set("pdf6_slices", "base", 2**31), None),
    "palette 'count'": (_palette("pdf6_scale", "count", None), None),
    "palette lies outside": (_palette("pdf6_scale", "offset", 10**9), None),
    "bit patterns": (_narrow_palette, None),
    "damaged|inflate": (None, _flip_deflated),
    "beyond its 3 values": (None, _codes_beyond_palette),
}


@pytest.fixture(scope="module")
def compact_alu(tmp_path_factory):
    path = tmp_path_factory.mktemp("v2") / "alu.btfm"
    return container.write_container(path, MLVQBTF.from_directory(shared_material("alu")))


@pytest.mark.parametrize("case", list(HEADER_CASES))
def test_a_damaged_encoding_is_one_error_naming_the_file(tmp_path, compact_alu, case):
    path = tmp_path / "m.btfm"
    path.write_bytes(compact_alu.read_bytes())
    edit_header, edit_body = HEADER_CASES[case]
    _rewrite(path, edit_header, edit_body)
    with pytest.raises(BTFFormatError, match=case) as err:
        load_btf(path)
    assert str(path) in str(err.value)


def test_an_encoding_in_a_version_1_file_is_refused(tmp_path, compact_alu):
    path = tmp_path / "m.btfm"
    blob = bytearray(compact_alu.read_bytes())
    blob[8:12] = (1).to_bytes(4, "little")
    data = bytes(blob[:-40])
    path.write_bytes(data + hashlib.sha256(data).digest() + container.END_MAGIC)
    with pytest.raises(BTFFormatError, match="version 1 file"):
        load_btf(path)

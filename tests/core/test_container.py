"""The .btfm container: exact round trips, atomic writes, clear errors for damaged files."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import random_hemisphere, shared_material

from btf_addon.core import fileio
from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import leather
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.errors import BTFFormatError, UnsupportedBTFError
from btf_addon.core.formats import container
from btf_addon.core.formats.load import load_btf
from btf_addon.core.grid import uniform_ring_grid


def _btfs():
    return {
        "lambertian": lambda: LambertianBTF((0.8, 0.5, 0.2)),
        "ggx": lambda: GGXBTF(0.7, 0.45),
        "dense": lambda: tabulate(
            LambertianBTF(0.3), uniform_ring_grid(30.0), uniform_ring_grid(30.0)
        ),
        "leather": lambda: leather(texels=4, fine_per_texel=4),
        "mlvq": lambda: MLVQBTF.from_directory(shared_material("alu")),
    }


@pytest.mark.parametrize("codec", list(_btfs()))
def test_round_trip_is_exact(tmp_path, rng, codec):
    btf = _btfs()[codec]()
    path = container.write_container(tmp_path / "m.btfm", btf)
    back = load_btf(path)
    assert back.meta.to_json() == btf.meta.to_json()
    for name, table in btf.tables().items():
        np.testing.assert_array_equal(back.tables()[name], table)
    n = 300
    uv, wi, wo = rng.random((n, 2)), random_hemisphere(rng, n), random_hemisphere(rng, n)
    np.testing.assert_array_equal(back.evaluate(uv, wi, wo), btf.evaluate(uv, wi, wo))


@pytest.fixture
def saved(tmp_path):
    return container.write_container(tmp_path / "g.btfm", GGXBTF(0.5, 0.5))


def test_truncated_file_is_rejected(saved):
    blob = saved.read_bytes()
    for cut in (10, len(blob) // 2, len(blob) - 1):
        saved.write_bytes(blob[:cut])
        with pytest.raises(BTFFormatError, match=str(saved.name)):
            load_btf(saved)


def test_flipped_byte_fails_the_checksum(saved):
    blob = bytearray(saved.read_bytes())
    blob[len(blob) // 2] ^= 0x40
    saved.write_bytes(bytes(blob))
    with pytest.raises(BTFFormatError, match="checksum"):
        load_btf(saved)


def test_not_a_container(tmp_path):
    f = tmp_path / "x.btfm"
    f.write_text("hello, this is not a BTF at all, just text that is long enough" * 3)
    with pytest.raises(BTFFormatError, match="not a BTF container"):
        load_btf(f)


def test_future_version_asks_for_an_update(saved):
    blob = bytearray(saved.read_bytes())
    blob[8:12] = (99).to_bytes(4, "little")
    saved.write_bytes(bytes(blob))
    with pytest.raises(UnsupportedBTFError, match="update the add-on"):
        load_btf(saved)


def test_failed_write_leaves_no_file_and_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "out.btfm"
    original = container.write_container(target, LambertianBTF(0.5))
    before = original.read_bytes()

    class Exploding(GGXBTF):
        def tables(self):
            tables = super().tables()
            tables["bad"] = np.zeros(3, dtype=np.complex64)  # unsupported dtype: write fails
            return tables

    with pytest.raises(ValueError, match="unsupported dtype"):
        container.write_container(target, Exploding(0.5, 0.5))
    monkeypatch.setattr(fileio.os, "fsync", _raise_oserror)  # the disk fills at the end
    with pytest.raises(OSError):
        container.write_container(target, GGXBTF(0.5, 0.5))
    assert target.read_bytes() == before  # the previous file is intact
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.btfm"]  # no temporaries left


def _raise_oserror(*_args):
    raise OSError(28, "No space left on device")

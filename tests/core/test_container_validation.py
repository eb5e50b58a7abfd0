"""The .btfm header behind a valid checksum: every field's type and range is checked before
any array is built, and each refusal is a BTFFormatError naming the file."""

from __future__ import annotations

import hashlib
import json
import struct

import pytest
from helpers import shared_material

from btf_addon.core.codecs.analytic import GGXBTF
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.errors import BTFError, BTFFormatError
from btf_addon.core.formats import container
from btf_addon.core.formats.load import load_btf


def rewrite(path, edit) -> None:
    """Apply ``edit(header) -> header`` and write the file back with a valid checksum (the
    damage a buggy writer makes, which the checksum cannot catch)."""
    blob = path.read_bytes()
    fixed = len(container.MAGIC) + 8
    _version, head_len = struct.unpack_from("<II", blob, len(container.MAGIC))
    header = json.loads(blob[fixed : fixed + head_len])
    start = fixed + head_len + (-(fixed + head_len)) % container.ALIGN
    body = blob[start : len(blob) - 40]
    text = json.dumps(edit(header)).encode()
    prefix = container.MAGIC + struct.pack("<II", container.FORMAT_VERSION, len(text)) + text
    prefix += b"\0" * ((-len(prefix)) % container.ALIGN)
    data = prefix + body
    path.write_bytes(data + hashlib.sha256(data).digest() + container.END_MAGIC)


def _first_array(h, **changes):
    h["arrays"][0].update(changes)
    return h


def _without(h, key):
    del h["arrays"][0][key]
    return h


CASES = {
    "header is a list": lambda h: [h],
    "no arrays key": lambda h: {k: v for k, v in h.items() if k != "arrays"},
    "arrays not a list": lambda h: {**h, "arrays": {"a": 1}},
    "params not an object": lambda h: {**h, "params": [1]},
    "missing offset": lambda h: _without(h, "offset"),
    "string shape": lambda h: _first_array(h, shape="12"),
    "string in shape": lambda h: _first_array(h, shape=["3"]),
    "negative shape": lambda h: _first_array(h, shape=[-1, -3]),
    "float shape": lambda h: _first_array(h, shape=[1.5]),
    "overflowing shape": lambda h: _first_array(h, shape=[2**62, 2**62, 4]),
    "negative offset": lambda h: _first_array(h, offset=-64),
    "offset outside": lambda h: _first_array(h, offset=10**12),
    "unknown dtype": lambda h: _first_array(h, dtype="<c16"),
    "dtype not a string": lambda h: _first_array(h, dtype=4),
    "repeated name": lambda h: {**h, "arrays": h["arrays"] * 2},
    "too many dimensions": lambda h: _first_array(h, shape=[1] * 20),
}


@pytest.fixture
def saved(tmp_path):
    return container.write_container(tmp_path / "g.btfm", GGXBTF(0.5, 0.5))


@pytest.mark.parametrize("case", list(CASES))
def test_header_fields_are_checked_before_allocation(saved, case):
    rewrite(saved, CASES[case])
    with pytest.raises(BTFFormatError) as err:
        load_btf(saved)
    assert str(saved) in str(err.value)


@pytest.mark.parametrize(
    ("text", "field"),
    [
        (b'{"codec": "ggx", "params": {"roughness": NaN}}', "params.roughness is nan"),
        (b'{"a": Infinity}', "a is inf"),
        (b'{"params": {"rgb": [1, 2, -Infinity]}}', "params.rgb[2] is -inf"),
    ],
)
def test_non_finite_numbers_in_the_header_are_refused(saved, text, field):
    """Refused, naming the field (issue 30 item 16: the message named only "NaN")."""
    rewrite(saved, lambda h: h)  # a valid file first, then its header replaced by raw text
    blob = saved.read_bytes()
    fixed = len(container.MAGIC) + 8
    _v, head_len = struct.unpack_from("<II", blob, len(container.MAGIC))
    start = fixed + head_len + (-(fixed + head_len)) % container.ALIGN
    body = blob[start : len(blob) - 40]
    prefix = container.MAGIC + struct.pack("<II", 1, len(text)) + text
    prefix += b"\0" * ((-len(prefix)) % container.ALIGN)
    data = prefix + body
    saved.write_bytes(data + hashlib.sha256(data).digest() + container.END_MAGIC)
    with pytest.raises(BTFFormatError) as err:
        load_btf(saved)
    assert f"{saved}: header field {field}: it must be a finite number" in str(err.value)


@pytest.fixture(scope="module")
def mlvq_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("mlvq") / "alu.btfm"
    return container.write_container(path, MLVQBTF.from_directory(shared_material("alu")))


@pytest.mark.parametrize(
    ("key", "value"),
    [("hdr_value", -2.0), ("n_beta", "5"), ("n_phi", 0), ("use_cos_beta", 1), ("name", None)],
)
def test_codec_parameters_are_typed_and_ranged(tmp_path, mlvq_file, key, value):
    path = tmp_path / "m.btfm"
    path.write_bytes(mlvq_file.read_bytes())
    rewrite(path, lambda h: {**h, "params": {**h["params"], key: value}})
    with pytest.raises(BTFFormatError, match=key):
        load_btf(path)


def test_table_checks_name_the_file_not_only_the_material(tmp_path, mlvq_file):
    path = tmp_path / "m.btfm"
    path.write_bytes(mlvq_file.read_bytes())

    # Five columns claimed for a table of n_beta columns: shape and bytes agree, codec refuses.
    def edit(h):
        for e in h["arrays"]:
            if e["name"] == "pdf1":
                rows, cols = e["shape"]
                if (rows * cols) % 5 == 0:
                    e["shape"] = [rows * cols // 5, 5]
                else:
                    e["shape"] = [rows * cols, 1]
        return h

    rewrite(path, edit)
    with pytest.raises(BTFError) as err:
        load_btf(path)
    assert str(path) in str(err.value) and "pdf1" in str(err.value)

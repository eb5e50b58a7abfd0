"""BTFbase text tables: a file cut inside its last number, bad tokens by line, the material
line's name and HDR multiplier: refused with the file (and line) named."""

from __future__ import annotations

import shutil

import pytest
from helpers import shared_material

from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.errors import BTFFormatError


@pytest.fixture
def alu(tmp_path):
    dst = tmp_path / "alu"
    shutil.copytree(shared_material("alu"), dst)
    return dst


def test_a_table_cut_inside_its_last_number_is_refused(alu):
    f = alu / "all_PDF3Dscale.txt"
    data = f.read_bytes().rstrip()
    f.write_bytes(data[:-2])  # "0.999448" → "0.9994": the count is right, the value is not
    with pytest.raises(BTFFormatError, match=r"all_PDF3Dscale\.txt: line \d+: .*ends inside"):
        MLVQBTF.from_directory(alu)


def test_a_bad_token_is_named_with_its_line(alu):
    f = alu / "all_PDF3Dscale.txt"
    lines = f.read_text().splitlines()
    lines[3] = lines[3].replace("0.", "x.", 1)
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(BTFFormatError, match=r"all_PDF3Dscale\.txt: line 4: 'x\.\d+' is not"):
        MLVQBTF.from_directory(alu)


def test_nan_in_a_table_is_named_with_its_line(alu):
    f = alu / "all_PDF3Dscale.txt"
    lines = f.read_text().splitlines()
    lines[2] = "nan " + " ".join(lines[2].split()[1:])
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(BTFFormatError, match=r"line 3: NaN or infinite"):
        MLVQBTF.from_directory(alu)


def _material_line(alu, edit) -> None:
    f = alu / "all_materialInfo.txt"
    lines = f.read_text().splitlines()
    fields = lines[14].split()
    lines[14] = " ".join(edit(fields))
    f.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda f: [*f[:8], "nan"], "non-finite"),
        (lambda f: [*f[:8], "-3.5"], "HDR multiplier must be ≥ 0"),
        (lambda f: ["../alu", *f[1:]], "not a plain file name"),
    ],
)
def test_material_line_values_are_checked(alu, edit, message):
    _material_line(alu, edit)
    with pytest.raises(BTFFormatError, match=message) as err:
        MLVQBTF.from_directory(alu)
    assert "all_materialInfo.txt" in str(err.value)


def test_a_value_beyond_float32_is_named_with_its_line(alu):
    f = alu / "all_PDF3Dscale.txt"
    lines = f.read_text().splitlines()
    lines[5] = "1e308 " + " ".join(lines[5].split()[1:])
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(BTFFormatError, match=r"all_PDF3Dscale\.txt: line 6: '1e308' is beyond"):
        MLVQBTF.from_directory(alu)

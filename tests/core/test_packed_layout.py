"""The packed GPU table layout has one definition (core/codecs/packed.py): device code spells no
slot.

The device halves of this check compile the layout into an OpenCL kernel and a GLSL shader and
read every value back (tests/kernels/test_programs.py, tests/gl/test_glsl_decode.py,
tests/blender/test_gpu_query.py).
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from helpers import ROOT

from btf_addon.core.codecs import packed
from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF, PrincipledBTF
from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.errors import UnsupportedBTFError
from btf_addon.core.grid import uniform_ring_grid
from btf_addon.core.model import BTFMeta, DelegatingBTF

DEVICE_FILES = sorted(
    [*(ROOT / "kernels").rglob("*.cl"), *(ROOT / "kernels").rglob("*.h"), *ROOT.glob("shaders/*")]
)
LAYOUT_NAME = r"(?:H|F|CODEC)_[A-Z0-9_]+|TABLE_WIDTH|HEADER_INTS|HEADER_FLOATS|PACKED_MAGIC"


def _code(path) -> str:
    """The file without comments, so prose about the layout does not count as a use."""
    text = re.sub(r"/\*.*?\*/", " ", path.read_text(), flags=re.S)
    return re.sub(r"//[^\n]*", " ", text)


def test_no_device_file_writes_a_layout_number_by_hand():
    """No #define or enum of a layout name in kernels/ or shaders/: the numbers come only from
    packed.defines() at build time."""
    assert len(DEVICE_FILES) >= 10  # the walk found the device code
    by_hand = []
    for path in DEVICE_FILES:
        code = _code(path)
        by_hand += [
            (path.name, m.group(0)) for m in re.finditer(rf"#\s*define\s+({LAYOUT_NAME})\b", code)
        ]
        for body in re.findall(r"\benum\b[^{;]*\{([^}]*)\}", code):
            by_hand += [(path.name, name) for name in re.findall(LAYOUT_NAME, body)]
    assert by_hand == []


def test_every_layout_name_in_device_code_is_defined():
    """A slot renamed in Python but not in a kernel (or a typo there) fails here, before any
    compiler runs; the names of each kind really occur, so the scan sees them."""
    defined = packed.defines()
    used = {}
    for path in DEVICE_FILES:
        for name in re.findall(rf"\b({LAYOUT_NAME})\b", _code(path)):
            used.setdefault(name, path.name)
    # F_ matches kernel identifiers such as F_ (the float stream) only with a suffix.
    unknown = {name: where for name, where in used.items() if name not in defined}
    assert unknown == {}
    for prefix in ("H_", "F_", "CODEC_"):
        assert any(name.startswith(prefix) for name in used), prefix
    assert "TABLE_WIDTH" in used


def test_defines_are_the_python_layout():
    d = packed.defines()
    for i, name in enumerate(packed.INT_HEADER):
        assert d[f"H_{name.upper()}"] == i
    first = 0
    for name, size in packed.FLOAT_HEADER:
        assert d[f"F_{name.upper()}"] == first
        first += size
    assert first <= packed.HEADER_FLOATS and len(packed.INT_HEADER) <= packed.HEADER_INTS
    assert d["TABLE_WIDTH"] == packed.TABLE_WIDTH and d["PACKED_MAGIC"] == packed.MAGIC
    codec_ids = {k: v for k, v in d.items() if k.startswith("CODEC_")}
    assert set(codec_ids) == {
        "CODEC_MLVQ",
        "CODEC_LAMBERTIAN",
        "CODEC_GGX",
        "CODEC_DENSE",
        "CODEC_PRINCIPLED",
        "CODEC_SVD",
    }
    assert len(set(codec_ids.values())) == len(codec_ids) and min(codec_ids.values()) > 0
    assert all(isinstance(v, int) for v in d.values())  # valid as -D and #define values


def _header(tables: packed.PackedTables) -> tuple[np.ndarray, np.ndarray]:
    return tables.ints.ravel()[: packed.HEADER_INTS], tables.floats.ravel()[: packed.HEADER_FLOATS]


@pytest.mark.parametrize(
    ("btf", "codec"),
    [
        (LambertianBTF((0.8, 0.5, 0.2)), "LAMBERTIAN"),
        (GGXBTF((0.9, 0.7, 0.5), 0.35), "GGX"),
        (PrincipledBTF((0.9, 0.6, 0.3), 0.4, 0.3, 0.7), "PRINCIPLED"),
    ],
)
def test_header_slots_read_back_by_their_define(btf, codec):
    """What device code reads at ITAB(H_x) / FTAB(F_x) is what the codec set."""
    d = packed.defines()
    ints, floats = _header(packed.pack(btf))
    assert ints[d["H_MAGIC"]] == packed.MAGIC
    assert ints[d["H_CODEC"]] == d[f"CODEC_{codec}"]
    albedo = btf.base_color if codec == "PRINCIPLED" else btf.albedo
    np.testing.assert_array_equal(floats[d["F_ALBEDO"] : d["F_ALBEDO"] + 3], np.float32(albedo))
    if codec != "LAMBERTIAN":
        assert floats[d["F_ALPHA2"]] == np.float32(btf.alpha2)
    if codec == "PRINCIPLED":
        assert floats[d["F_METALLIC"]] == np.float32(btf.metallic)
        assert floats[d["F_SPECULAR_F0"]] == np.float32(btf.specular_f0)


def test_dense_tables_sit_at_their_header_offsets():
    d = packed.defines()
    grid = uniform_ring_grid(30.0)
    btf = tabulate(woven(texels=2, fine_per_texel=2), grid, grid)
    tables = packed.pack(btf)
    ints, floats = tables.ints.ravel(), tables.floats.ravel()
    assert ints[d["H_CODEC"]] == d["CODEC_DENSE"]
    assert (ints[d["H_WIDTH"]], ints[d["H_HEIGHT"]]) == (btf.meta.width, btf.meta.height)
    start = int(ints[d["H_F_DATA"]])
    np.testing.assert_array_equal(floats[start : start + btf.data.size], btf.data.ravel())
    rings = int(ints[d["H_N_LIGHT_RINGS"]])
    theta = int(ints[d["H_F_LIGHT_THETA"]])
    np.testing.assert_array_equal(floats[theta : theta + rings], btf.light_grid.theta_deg)


def test_a_codec_registers_beside_its_code(monkeypatch):
    """Adding a codec is one register_codec call (name, class, device id, pack function):
    pack dispatches to it by meta.codec, and a container finds its class by the same name."""
    monkeypatch.setattr(packed, "_CODECS", dict(packed._CODECS))

    class Constant(LambertianBTF):
        def __init__(self):
            super().__init__(0.5)
            self.meta = BTFMeta("constant", "c", 1, 1, 1, 1, "none")

    def pack_constant(btf, out):
        out.set(albedo=(1.0, 2.0, 3.0), f_data=out.float_table(np.arange(5.0)))

    packed.register_codec("constant", Constant, 9, pack_constant)
    assert packed.defines()["CODEC_CONSTANT"] == 9
    from btf_addon.core.formats.load import codec_class

    assert codec_class("constant") is Constant
    tables = packed.pack(Constant())
    ints, floats = _header(tables)
    assert ints[1] == 9 and list(floats[2:5]) == [1.0, 2.0, 3.0]
    start = int(ints[packed.INT_SLOT["f_data"]])
    assert start == packed.HEADER_FLOATS  # the first table follows the header
    assert list(tables.floats.ravel()[start : start + 5]) == [0, 1, 2, 3, 4]
    with pytest.raises(ValueError, match="taken"):
        packed.register_codec("other", Constant, 9, pack_constant)  # device constants are unique
    with pytest.raises(ValueError, match="invalid"):
        packed.register_codec("zero", Constant, 0, pack_constant)  # 0 is an empty header


def test_writer_refuses_unknown_slots_and_wrong_sizes():
    out = packed.TableWriter()
    with pytest.raises(KeyError):
        out.set(albedo_r=1.0)  # a typo cannot write nowhere
    with pytest.raises(ValueError, match="3 floats"):
        out.set(albedo=1.0)


def test_unregistered_codecs_and_huge_indices_are_refused():
    with pytest.raises(UnsupportedBTFError, match="tabulate procedural presets first"):
        packed.pack(woven(texels=2, fine_per_texel=2))
    out = packed.TableWriter()
    out.set(f_data=out.int_table(np.array([1 << 24])))
    with pytest.raises(UnsupportedBTFError, match="2\\^24"):
        out.finish("huge")


def test_a_delegating_wrapper_packs_the_btf_it_wraps():
    btf = GGXBTF((0.9, 0.7, 0.5), 0.35)
    wrapped = DelegatingBTF(DelegatingBTF(btf, btf._evaluate_valid), btf._evaluate_valid)
    a, b = packed.pack(btf), packed.pack(wrapped)
    np.testing.assert_array_equal(a.ints, b.ints)
    np.testing.assert_array_equal(a.floats, b.floats)
    q = np.array([[0.5, 0.5, 30.0, 10.0, 20.0, 200.0]])
    np.testing.assert_array_equal(wrapped.evaluate_angles(q), btf.evaluate_angles(q))
    assert wrapped.meta is btf.meta and wrapped.params() == btf.params()

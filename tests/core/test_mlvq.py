"""BTFbase MLVQ decoding on the real shared materials, against an independent scalar decoder."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from helpers import random_queries
from scalar_mlvq import ScalarMLVQ

from btf_addon.core.codecs.mlvq import LDR_VALUE_SCALE, MLVQBTF
from btf_addon.core.errors import BTFFormatError, UnsupportedBTFError


def test_decoder_matches_independent_scalar_decoder(material_dir, rng):
    btf = MLVQBTF.from_directory(material_dir)
    ref = ScalarMLVQ(material_dir)
    q = random_queries(rng, 400)
    # Grid-aligned and wrap-around cases the random draw would rarely hit.
    q = np.vstack(
        [
            q,
            [
                [0.0, 0.0, 0, 0, 0, 0],
                [0.999999, 0.999999, 90, 359.99, 90, 359.99],
                [0.5, 0.5, 45, 360, 15, 337.5],
                [0.25, 0.75, 90, 90, 0, 0],
                [0.1, 0.9, 75, 180, 75, 22.5],
            ],
        ]
    )
    got = btf.evaluate_angles(q).astype(np.float64) / LDR_VALUE_SCALE
    want = np.array([ref.decode(*row) for row in q])
    # float32 output storage: relative 1e-6 of values up to ~255, plus float64 noise.
    np.testing.assert_allclose(got, want, rtol=2e-6, atol=1e-4)
    assert want.max() > 50  # the comparison covered real, non-trivial values


def test_decoded_values_are_finite_and_non_negative(material_dir, rng):
    btf = MLVQBTF.from_directory(material_dir)
    v = btf.evaluate_angles(random_queries(rng, 20000))
    assert np.all(np.isfinite(v)) and v.min() >= 0.0
    assert v.max() > 0.0


def test_raw_size_matches_the_tools_quantisation_report():
    from helpers import shared_material

    btf = MLVQBTF.from_directory(shared_material("alu"))
    assert (btf.meta.width, btf.meta.height) == (64, 64)
    assert btf.meta.raw_bytes == 80_621_568  # "uncompressed = 80621568" in quantreport.txt


def test_phi_wraps_continuously_across_360(material_dir):
    btf = MLVQBTF.from_directory(material_dir)
    eps = 1e-4
    for phi in (0.0, 360.0 - 22.5 / 2):
        a = btf.evaluate_angles([[0.3, 0.6, 40, 10, 50, phi - eps]])
        b = btf.evaluate_angles([[0.3, 0.6, 40, 10, 50, phi + eps]])
        np.testing.assert_allclose(a, b, rtol=1e-3)


def test_texel_lookup_wraps():
    from helpers import shared_material

    btf = MLVQBTF.from_directory(shared_material("alu"))
    q = np.array([[0.3, 0.7, 30, 20, 40, 60]])
    shifted = q.copy()
    shifted[0, :2] += [3.0, -2.0]
    np.testing.assert_array_equal(btf.evaluate_angles(q), btf.evaluate_angles(shifted))


# --- corrupt, truncated, inconsistent materials ----------------------------------------------


@pytest.fixture
def alu_copy(tmp_path):
    from helpers import shared_material

    dst = tmp_path / "alu"
    shutil.copytree(shared_material("alu"), dst)
    for f in dst.iterdir():
        f.chmod(0o644)
    return dst


def test_truncated_table_names_the_file(alu_copy):
    f = alu_copy / "all_PDF2Dscale.txt"
    f.write_bytes(f.read_bytes()[: len(f.read_bytes()) // 2])
    with pytest.raises(BTFFormatError, match=r"all_PDF2Dscale\.txt.*truncated"):
        MLVQBTF.from_directory(alu_copy)


def test_missing_table_names_the_file(alu_copy):
    (alu_copy / "all_PDF3Dslices.txt").unlink()
    with pytest.raises(BTFFormatError, match=r"all_PDF3Dslices\.txt.*missing"):
        MLVQBTF.from_directory(alu_copy)


def test_index_out_of_range_is_rejected(alu_copy):
    f = alu_copy / "all_PDF4Dslices.txt"
    lines = f.read_text().splitlines()
    lines[1] = "99999 " + " ".join(lines[1].split()[1:])
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(BTFFormatError, match=r"PDF4Dslices → all_PDF3Dslices"):
        MLVQBTF.from_directory(alu_copy)


def test_garbage_token_is_rejected(alu_copy):
    f = alu_copy / "alu_PDF6Dscale.txt"
    head, body = f.read_text().split("\n", 1)
    f.write_text(head + "\n" + body.replace("0.9", "zz", 1))
    with pytest.raises(BTFFormatError, match=r"alu_PDF6Dscale\.txt.*not a number"):
        MLVQBTF.from_directory(alu_copy)
    f.write_text("64 64 low high\n" + body)
    with pytest.raises(BTFFormatError, match=r"alu_PDF6Dscale\.txt: header must be"):
        MLVQBTF.from_directory(alu_copy)


def test_wrong_column_count_is_rejected(alu_copy):
    f = alu_copy / "all_PDF3Dscale.txt"
    lines = f.read_text().splitlines()
    head = lines[0].split()
    lines[0] = " ".join([head[0], "8", *head[2:]])
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(BTFFormatError, match=r"all_PDF3Dscale\.txt: expected 7 columns"):
        MLVQBTF.from_directory(alu_copy)


def test_not_a_material_directory(tmp_path):
    with pytest.raises(BTFFormatError, match=r"all_materialInfo\.txt is missing"):
        MLVQBTF.from_directory(tmp_path)


def test_multi_material_database_is_unsupported(alu_copy):
    f = alu_copy / "all_materialInfo.txt"
    lines = f.read_text().splitlines()
    lines[2] = "3"
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(UnsupportedBTFError, match="3 materials"):
        MLVQBTF.from_directory(alu_copy)


def test_hdr_path_matches_independent_decoder(alu_copy, rng):
    """No HDR BTFbase data ships here: re-label alu as HDR (hdrValue 2.5) so the decoder takes
    the LogLuv path, and compare with the scalar reference's own LogLuv implementation."""
    for name in ("all_materialInfo.txt", "alu_materialInfo.txt"):
        f = alu_copy / name
        f.write_text(f.read_text().replace("64 64 0.000000", "64 64 2.500000"))
    btf = MLVQBTF.from_directory(alu_copy)
    assert btf.meta.hdr and btf.p.hdr_value == 2.5
    ref = ScalarMLVQ(alu_copy)
    q = random_queries(rng, 200)
    got = btf.evaluate_angles(q).astype(np.float64) / btf.meta.value_scale
    want = np.array([ref.decode(*row) for row in q])
    np.testing.assert_allclose(got, want, rtol=2e-6, atol=1e-6 * want.max())
    assert want.max() > 0


def test_logluv_white_point_decodes_to_grey():
    """u', v' of the D65 white point (0.1978, 0.4683) × 410 must give R = G = B."""
    from btf_addon.core.colour import logluv_to_rgb

    rgb = logluv_to_rgb(
        np.array([50.0, 500.0, 1500.0]), np.full(3, 0.1978 * 410), np.full(3, 0.4683 * 410)
    )
    np.testing.assert_allclose(rgb / rgb[:, 1:2], 1.0, atol=0.01)
    assert np.all(np.diff(rgb[:, 1]) > 0)  # brighter codes, brighter grey


def test_texels_without_data_decode_to_zero(alu_copy):
    f = alu_copy / "alu_PDF6Dslices.txt"
    lines = f.read_text().splitlines()
    row = lines[1].split()
    row[0] = "0"  # texel (x=0, y=0): "not compressed"
    lines[1] = " ".join(row)
    f.write_text("\n".join(lines) + "\n")
    btf = MLVQBTF.from_directory(alu_copy)
    v = btf.evaluate_angles([[0.001, 0.001, 30, 0, 20, 0], [0.02, 0.001, 30, 0, 20, 0]])
    assert np.all(v[0] == 0) and v[1].max() > 0

"""UBO2014 DFMF .btf: hand-built bytes from the published layout, our writer's round trip, and
the hard cases."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from ubo2014_files import YUV_TO_RGB, hand_built

from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.codecs.svd_build import factorise
from btf_addon.core.errors import BTFFormatError, UnsupportedBTFError
from btf_addon.core.formats.load import load_btf
from btf_addon.core.formats.ubo2014 import load_ubo2014, read_ubo2014
from btf_addon.core.formats.ubo2014_writer import dfmf_bytes, write_ubo2014
from btf_addon.core.grid import uniform_ring_grid


def test_hand_built_file_decodes_to_the_expected_values(tmp_path):
    blob, src = hand_built()
    path = tmp_path / "hand.btf"
    path.write_bytes(blob)
    meta, u, sv = read_ubo2014(path)
    assert meta.version == 4 and meta.cosine_in_data and meta.channel_names == ["Y", "U", "V"]
    assert meta.rgb_scale == (1.0, 0.5, 2.0) and len(meta.rotations) == 1 and meta.xml == "<x/>"
    for c in range(3):
        np.testing.assert_array_equal(u[c], src["u"][c])
        np.testing.assert_array_equal(sv[c], src["sv"][c])
    btf = load_btf(path)  # dispatch on the signature
    assert btf.meta.codec == "svd" and (btf.meta.width, btf.meta.height) == (2, 1)
    assert btf.meta.tile_size_mm == (2 / 40.0, 1 / 40.0)
    # Every (view, light, texel) of the file, queried at its own angles: by hand,
    # rgb = YUV→RGB(Σ U·SV) · scale, value = rgb/π (the cosine is in the data).
    for v, (tv, pv) in enumerate(src["views"]):
        for li, (tl, pl) in enumerate(src["lights"]):
            row = v * len(src["lights"]) + li
            for x in (0, 1):
                y = [float(src["u"][c][row] @ src["sv"][c][x]) for c in range(3)]
                want = YUV_TO_RGB @ np.array(y) * (1.0, 0.5, 2.0) / np.pi
                q = [(x + 0.5) / 2, 0.5, *np.degrees([tl, pl, tv, pv])]
                got = btf.evaluate_angles(np.array([q]))[0]
                np.testing.assert_allclose(got, np.maximum(want, 0), rtol=1e-5, atol=1e-7)


def test_older_meta_versions_and_half_scalars(tmp_path):
    blob, src = hand_built(version=1, scalar=2)
    path = tmp_path / "v1.btf"
    path.write_bytes(blob)
    meta, u, _ = read_ubo2014(path)
    assert meta.version == 1 and not meta.cosine_in_data and meta.channel_names == ["R", "G", "B"]
    np.testing.assert_array_equal(u[0], src["u"][0].astype(np.float16).astype(np.float32))


@pytest.fixture(scope="module")
def synthetic():
    src = tabulate(
        woven(texels=4, fine_per_texel=4), uniform_ring_grid(20.0), uniform_ring_grid(15.0)
    )
    return src, src.data * np.pi


@pytest.mark.parametrize("scalar", [2, 4])
def test_writer_round_trip(tmp_path, synthetic, scalar):
    """read == written (half: the factors rounded to half precision, as written), and the
    decode at the measured directions equals the source within the rank's truncation error
    (reported) plus the half rounding (5e-3 of the peak)."""
    src, data = synthetic
    svd, errors = factorise(data, src.view_grid, src.light_grid, ranks=(6, 3, 3))
    path = tmp_path / "w.btf"
    write_ubo2014(path, svd, scalar_size=scalar)
    back = load_ubo2014(path)
    dtype = np.float16 if scalar == 2 else np.float32
    for c in range(3):
        np.testing.assert_array_equal(back.u[c], svd.u[c].astype(dtype).astype(np.float32))
        np.testing.assert_array_equal(back.sv[c], svd.sv[c].astype(dtype).astype(np.float32))
    assert back.p.view_grid.counts == src.view_grid.counts
    np.testing.assert_allclose(back.p.light_grid.theta_deg, src.light_grid.theta_deg, atol=1e-4)
    nv, nl, h, w, _ = data.shape
    pair = np.repeat(np.arange(nv * nl), h * w)
    texel = np.tile(np.arange(h * w), nv * nl)
    got = back.pair_rgb(pair, texel).reshape(data.shape)
    rel = np.linalg.norm(got - data) / np.linalg.norm(data)
    bound = np.linalg.norm(errors) + (5e-3 if scalar == 2 else 1e-6)
    assert rel <= bound, (rel, errors)


def _write(tmp_path, blob: bytes):
    path = tmp_path / "bad.btf"
    path.write_bytes(blob)
    return path


def test_hard_cases_end_in_one_clear_error(tmp_path):
    blob, _ = hand_built()
    # Channel 0 starts after the DFMF header; channel c takes 13 + 4·K·(1 + 12 rows + 2 cols).
    channel0 = len(blob) - (13 + 4 * 2 * 15) - 2 * (13 + 4 * 15)
    cases = [
        (blob[:-7], BTFFormatError, "truncated"),
        (blob[:5], BTFFormatError, "truncated"),
        (b"!XYZ00" + blob[6:], BTFFormatError, "not a UBO2014"),
        (b"!FMF12FCER" + blob[10:], UnsupportedBTFError, "FMF12FCER"),
        (blob + b"\0", BTFFormatError, "trailing"),
        # channel 0 claims 2^31 rows: refused from the sizes, before allocating terabytes
        (
            blob[: channel0 + 5] + struct.pack("<I", 1 << 31) + blob[channel0 + 9 :],
            BTFFormatError,
            "components of",
        ),
        (blob[:channel0] + b"\x03" + blob[channel0 + 1 :], BTFFormatError, "scalar size 3"),
    ]
    nan = bytearray(blob)
    first_u = channel0 + 13 + 2 * 4  # after the channel header and S[2]
    nan[first_u : first_u + 4] = struct.pack("<f", float("nan"))
    cases.append((bytes(nan), BTFFormatError, "NaN"))
    meta = bytearray(blob)
    meta[10:14] = struct.pack("<I", 999)  # meta block size
    cases.append((bytes(meta), BTFFormatError, "meta block"))
    for data, error, message in cases:
        with pytest.raises(error, match=message):
            load_ubo2014(_write(tmp_path, data))


def test_rotated_rings_round_trip_and_duplicates_are_refused(tmp_path, rng):
    """A file whose rings are rotated and uneven keeps its azimuths (written and read back) and
    decodes at its own samples; two samples at one direction are one clear error."""
    from svd_cases import svd_cases

    btf = svd_cases()["rotated-rings"]
    path = tmp_path / "rot.btf"
    write_ubo2014(path, btf, scalar_size=4)
    back = load_ubo2014(path)
    np.testing.assert_allclose(back.p.phis("view"), btf.p.phis("view"), atol=1e-4)
    np.testing.assert_allclose(back.p.phis("light"), btf.p.phis("light"), atol=1e-4)
    q = np.column_stack([rng.random((500, 2)), rng.random((500, 4)) * [90, 360, 90, 360]])
    np.testing.assert_allclose(
        back.evaluate_angles(q), btf.evaluate_angles(q), rtol=1e-4, atol=1e-6
    )
    blob = bytearray(dfmf_bytes(btf, 4))
    n_lights = btf.p.light_grid.size
    first_view = blob.index(struct.pack("<I", btf.p.view_grid.size)) + 4
    stride = 12 + 8 * n_lights
    second = first_view + stride  # view 1: copy view 2's direction onto it
    blob[second : second + 8] = blob[second + stride : second + stride + 8]
    with pytest.raises(BTFFormatError, match="same azimuth"):
        load_ubo2014(_write(tmp_path, bytes(blob)))


def test_file_rows_start_at_the_image_top(tmp_path, synthetic):
    """btflib's texel index x + width·y counts y from the image's top; ours from v = 0."""
    src, data = synthetic
    svd, _ = factorise(data, src.view_grid, src.light_grid, ranks=(2, 1, 1))
    path = tmp_path / "rows.btf"
    write_ubo2014(path, svd, scalar_size=4)
    _, _, raw_sv = read_ubo2014(path)
    w = svd.p.width
    top_row_ours = svd.sv[0].reshape(svd.p.height, w, -1)[-1]
    np.testing.assert_array_equal(raw_sv[0][:w], top_row_ours)

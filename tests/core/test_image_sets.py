"""UBO2003/ATRIUM image sets and the Radiance .hdr reader."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from btf_addon.core.errors import BTFError, BTFFormatError
from btf_addon.core.formats.image_sets import iter_set_names, load_image_set
from btf_addon.core.formats.load import load_btf
from btf_addon.core.formats.radiance_hdr import decode_hdr, encode_hdr
from btf_addon.core.grid import UBO2003


@pytest.fixture(scope="module")
def factors():
    """A synthetic measurement: (81, 81, 4, 4, 3) reflectance factors in [0.02, 1]."""
    rng = np.random.default_rng(11)
    return rng.uniform(0.02, 1.0, (UBO2003.size, UBO2003.size, 4, 4, 3)).astype(np.float32)


def _image(factors, v, li):
    return factors[v, li][::-1]  # texel row 0 is v = 0, the image's bottom row


def test_hdr_round_trip_within_rgbe_precision(rng):
    rgb = rng.uniform(0, 50, (5, 9, 3))
    rgb[0, 0] = 0
    back = decode_hdr(encode_hdr(rgb))
    # RGBE keeps 8 mantissa bits of each pixel's largest channel: error < 2^-8 of that.
    assert np.all(np.abs(back - rgb) <= rgb.max(axis=2, keepdims=True) / 256 + 1e-12)


def test_hdr_run_length_scanline_built_by_hand():
    """One 10-pixel scanline, new-style RLE from the format description: R a run of 10 × 128,
    G literals 0..9 (+128), B a run of 5 × 64 then 5 literals 64, E a run of 10 × 129."""
    head = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=2.0\n\n-Y 1 +X 10\n"
    line = bytes([2, 2, 0, 10])
    line += bytes([128 + 10, 128])
    line += bytes([10, *range(128, 138)])
    line += bytes([128 + 5, 64, 5, 64, 64, 64, 64, 64])
    line += bytes([128 + 10, 129])
    img = decode_hdr(head + line)
    # value = (m + 0.5)·2^(129 − 136) / exposure
    scale = 2.0 ** (129 - 136) / 2.0
    np.testing.assert_allclose(img[0, :, 0], 128.5 * scale)
    np.testing.assert_allclose(img[0, :, 1], (np.arange(128, 138) + 0.5) * scale)
    np.testing.assert_allclose(img[0, :, 2], 64.5 * scale)


def test_hdr_hard_cases():
    good = encode_hdr(np.ones((2, 3, 3)))
    for data, message in (
        (b"P6\n", "not a Radiance"),
        (good[:-5], "truncated"),
        (good.replace(b"-Y 2 +X 3", b"+Y 2 +X 3"), "resolution line"),
        (good.replace(b"-Y 2", b"-Y 99999999"), "invalid"),
    ):
        with pytest.raises(BTFFormatError, match=message):
            decode_hdr(data)


@pytest.fixture(scope="module")
def hdr_folder(tmp_path_factory, factors):
    folder = tmp_path_factory.mktemp("ATRIUM_TEST")
    for name, v, li in iter_set_names(".hdr"):
        (folder / name).write_bytes(encode_hdr(_image(factors, v, li)))
    return folder


def test_hdr_set_in_a_folder_imports_to_the_same_values(hdr_folder, factors):
    btf = load_btf(hdr_folder)
    assert btf.meta.codec == "dense" and (btf.meta.width, btf.meta.height) == (4, 4)
    got = btf.data * np.pi
    # RGBE: within 2^-8 of each pixel's largest channel.
    assert np.all(np.abs(got - factors) <= factors.max(axis=-1, keepdims=True) / 256 + 1e-7)
    # A reduced copy is the box filter of the full one.
    half = load_image_set(hdr_folder, texels=2)
    want = btf.data.reshape(81, 81, 2, 2, 2, 2, 3).mean(axis=(3, 5))
    np.testing.assert_allclose(half.data, want, rtol=1e-5, atol=1e-7)


def test_jpeg_set_in_a_zip_imports_to_the_same_values(tmp_path, factors):
    pil = pytest.importorskip("PIL.Image")
    path = tmp_path / "UBO_TEST.zip"
    eight = np.round(factors * 255).astype(np.uint8)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as z:
        for name, v, li in iter_set_names(".jpg"):
            buf = io.BytesIO()
            pil.fromarray(_image(eight, v, li)).save(buf, "JPEG", quality=100, subsampling=0)
            z.writestr(f"UBO_TEST/{name}", buf.getvalue())
    err = np.abs(load_btf(path).data * np.pi * 255 - eight)
    # JPEG at quality 100 without chroma subsampling, on noise: a few levels at most,
    # about one on average.
    assert err.max() <= 6 and err.mean() <= 1.0, (err.max(), err.mean())


def test_incomplete_off_grid_or_oversized_sets_are_one_clear_error(tmp_path, hdr_folder):
    partial = tmp_path / "partial"
    partial.mkdir()
    for name, _, _ in list(iter_set_names(".hdr"))[:100]:
        (partial / name).write_bytes((hdr_folder / name).read_bytes())
    with pytest.raises(BTFFormatError, match="100 of the 6561 images"):
        load_image_set(partial)
    (partial / "tl007 pl000 tv000 pv000.hdr").write_bytes(b"")
    with pytest.raises(BTFFormatError, match="not on the UBO2003"):
        load_image_set(partial)
    with pytest.raises(BTFError, match=r"need .* GiB as a dense table"):
        load_image_set(hdr_folder, max_bytes=1000)
    # "auto" (what load_btf and the import operator use) reduces until it fits instead.
    auto = load_image_set(hdr_folder, texels="auto", max_bytes=81 * 81 * 2 * 2 * 12)
    assert auto.meta.width == 2 and "2×2 texels of 4×4" in auto.meta.extra["reduced"]

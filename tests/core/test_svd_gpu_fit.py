"""GPU limits before upload: too-large svd/dense BTFs get a reduced-resolution copy and a
message; one that cannot fit at all is one clear error."""

from __future__ import annotations

import numpy as np
import pytest

from btf_addon.core.codecs.dense import DenseBTF
from btf_addon.core.codecs.gpu_fit import fit_for_gpu, packed_floats
from btf_addon.core.codecs.packed import pack
from btf_addon.core.codecs.svd_build import factorise
from btf_addon.core.errors import UnsupportedBTFError
from btf_addon.core.grid import uniform_ring_grid

GRID = uniform_ring_grid(30.0)  # 1 + 6 + 12 directions: small, cheap tests


@pytest.fixture(scope="module")
def svd():
    rng = np.random.default_rng(3)
    data = rng.random((GRID.size, GRID.size, 32, 32, 3)).astype(np.float32)
    return factorise(data, GRID, GRID, ranks=(4, 2, 2))[0]


def test_a_btf_that_fits_is_untouched(svd):
    btf, note = fit_for_gpu(svd)
    assert btf is svd and note is None


def test_too_large_svd_is_reduced_until_it_fits(svd):
    limit = 4 * packed_floats(svd) // 3  # a third of the bytes it needs
    btf, note = fit_for_gpu(svd, max_bytes=limit)
    assert btf.meta.width < 32 and "viewport draws it at" in note
    assert pack(btf).floats.nbytes <= limit + 4 * 4096  # the stream's last row is padded


def test_too_large_dense_is_reduced(svd):
    data = np.ones((GRID.size, GRID.size, 16, 16, 3), np.float32)
    dense = DenseBTF(data, GRID, GRID)
    btf, note = fit_for_gpu(dense, max_bytes=data.nbytes // 3)
    assert (btf.meta.width, btf.meta.height) == (8, 8) and note
    np.testing.assert_array_equal(btf.data, 1.0)  # a box filter of a constant


def test_nothing_fits_is_one_clear_error(svd):
    with pytest.raises(UnsupportedBTFError, match="even at 1×1 texels"):
        fit_for_gpu(svd, max_bytes=1000)

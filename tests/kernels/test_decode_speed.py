"""The fast MLVQ decode (kernels/include/btf_packed.h): its interleaved tables are exact copies
of the originals, and the device decode agrees with the numpy reference where float32 is
hardest (grazing light, β → ±90°; the view pole)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import shared_material

from btf_addon.core.mlvq import MLVQBTF
from btf_addon.core.packed import INT_SLOT, pack

pytestmark = pytest.mark.opencl


@pytest.fixture(scope="module")
def alu():
    return MLVQBTF.from_directory(shared_material("alu"))


def test_fast_tables_are_exact_copies(alu):
    p = pack(alu)
    ints, floats = p.ints.ravel(), p.floats.ravel()
    t = alu.t

    def at(slot, n, k):
        start = int(ints[INT_SLOT[slot]])
        return floats[start : start + n * k].reshape(n, k)

    f6 = at("f_mlvq6", t["pdf6_scale"].size, 2)
    np.testing.assert_array_equal(f6[:, 0], t["pdf6_scale"].ravel())
    np.testing.assert_array_equal(f6[:, 1], t["pdf6_slices"].ravel())
    f4 = at("f_mlvq4", t["pdf4_scale"].size, 2)
    np.testing.assert_array_equal(f4[:, 1], t["pdf4_slices"].ravel())
    f3 = at("f_mlvq3", t["pdf3_scale"].size, 4)
    np.testing.assert_array_equal(f3[:, 0], t["pdf3_scale"].ravel())
    np.testing.assert_array_equal(f3[:, 1:3], t["pdf2_indices"][t["pdf3_slices"].ravel()])
    assert int(ints[INT_SLOT["f_mlvq3"]]) % 4 == 0  # float4 rows never straddle a 16-byte line
    f2 = at("f_mlvq2", t["pdf2_scale"].size, 2)
    np.testing.assert_array_equal(f2[:, 0], t["pdf2_scale"].ravel())
    np.testing.assert_array_equal(f2[:, 1], t["pdf2_slices"].ravel())
    ab = at("f_mlvq_ab", t["index_ab"].size, 2)
    np.testing.assert_array_equal(ab, t["ab_colors"][t["index_ab"].ravel()])


def test_grazing_light_and_view_pole_match_the_reference(alu, rng):
    from btf_addon.cl.context import OpenCLUnavailableError, create_context
    from btf_addon.cl.evaluate import device_btf

    try:
        ctx = create_context()
    except OpenCLUnavailableError as exc:
        pytest.skip(str(exc))
    n = 4000
    q = np.column_stack(
        [
            rng.random(n),
            rng.random(n),
            np.full(n, 90.0),
            rng.random(n) * 360,
            rng.random(n) * 90,
            rng.random(n) * 360,
        ]
    )
    q[: n // 2, 5] = q[: n // 2, 3] + 90.0 + rng.normal(0, 0.5, n // 2)  # β within ~1° of 90°
    q[n // 2 : n // 2 + 200, 4] = 0.0  # view at the pole
    got, want = device_btf(alu, ctx).evaluate_angles(q), alu.evaluate_angles(q)
    # float32 against float64: β and α come from atan2 of the turned light vector, accurate to
    # a few ulps even at β = ±90° (the original's asin is not), so the test's general bound
    # holds here too: 2e-4 of the largest value absolute, 2e-3 relative.
    np.testing.assert_allclose(got, want, rtol=2e-3, atol=2e-4 * float(want.max()))

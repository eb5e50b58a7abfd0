"""OpenCL BTF evaluation against the numpy reference, on every device that builds programs."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import building_device_indices, random_queries, shared_material

from btf_addon.cl import programs
from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF, PrincipledBTF
from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import woven
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.errors import UnsupportedBTFError
from btf_addon.core.grid import uniform_ring_grid

DEVICES = building_device_indices()
pytestmark = pytest.mark.opencl


@pytest.fixture(params=DEVICES or [None], ids=lambda i: f"device{i}")
def device_context(request):
    if request.param is None:
        pytest.skip("no OpenCL device on this machine (setup installs PoCL: run `make setup`)")
    from btf_addon.cl.context import create_context

    return create_context(request.param)


def _btfs():
    return {
        "alu": lambda: MLVQBTF.from_directory(shared_material("alu")),
        "wallpaper": lambda: MLVQBTF.from_directory(shared_material("wallpaper")),
        "lambertian": lambda: LambertianBTF((0.8, 0.5, 0.2)),
        "ggx": lambda: GGXBTF((0.9, 0.7, 0.5), 0.35),
        "principled": lambda: PrincipledBTF((0.9, 0.6, 0.3), 0.4, 0.3, 0.7),
        "dense": lambda: tabulate(
            woven(texels=4, fine_per_texel=4), uniform_ring_grid(20.0), uniform_ring_grid(15.0)
        ),
    }


@pytest.mark.parametrize("name", list(_btfs()))
def test_device_matches_numpy_reference(device_context, rng, name):
    from btf_addon.cl.evaluate import device_btf

    btf = _btfs()[name]()
    device = device_btf(btf, device_context)
    q = random_queries(rng, 20_000)
    q[:50, 2] = 90.0  # grazing light
    q[50:100, 4] = 0.0  # view at the pole
    q[100:110] = np.nan  # sanitised on the host: zero, never sent to the device
    got, want = device.evaluate_angles(q), btf.evaluate_angles(q)
    assert np.all(got[100:110] == 0)
    # float32 device maths (sin/asin/pow in single precision) against the float64 reference:
    # 2e-4 of the largest value absolute, 2e-3 relative.
    np.testing.assert_allclose(got, want, rtol=2e-3, atol=2e-4 * float(want.max()))


def test_procedural_presets_are_refused_clearly(device_context):
    from btf_addon.cl.evaluate import device_btf

    with pytest.raises(UnsupportedBTFError, match="tabulate procedural presets first"):
        device_btf(woven(texels=2, fine_per_texel=4), device_context)


def test_programs_are_cached_in_memory_and_on_disk(device_context, tmp_path, monkeypatch):
    monkeypatch.setenv("BTF_CL_CACHE", str(tmp_path))
    monkeypatch.setattr(programs, "_memory_cache", {})
    defines = {"TEST_VARIANT": 1}
    before = dict(programs.stats)
    args = (device_context.context, device_context.device, "btf_eval.cl", defines)
    assert not programs.is_cached(*args)  # F12 says "compiling…" then
    programs.build_program(device_context.context, device_context.device, "btf_eval.cl", defines)
    assert programs.stats["compiled"] == before["compiled"] + 1
    assert programs.is_cached(*args)
    assert len(list(tmp_path.glob("*.bin"))) == 1
    programs.build_program(device_context.context, device_context.device, "btf_eval.cl", defines)
    assert programs.stats["memory_hits"] == before["memory_hits"] + 1
    monkeypatch.setattr(programs, "_memory_cache", {})  # as a new process would start
    assert programs.is_cached(*args)  # on disk
    programs.build_program(device_context.context, device_context.device, "btf_eval.cl", defines)
    assert programs.stats["disk_hits"] == before["disk_hits"] + 1
    assert programs.stats["compiled"] == before["compiled"] + 1


def test_includes_are_expanded_once():
    text = programs.expand_includes(programs.KERNELS_DIR / "btf_eval.cl")
    assert "#include" not in text
    assert text.count("inline float3 btf_logluv_to_rgb") == 1

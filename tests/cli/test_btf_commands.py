"""The command line as a user runs it: a real subprocess, exit codes, files, messages."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import cli_env, run_cli, shared_material, studiolights_dir

from btf_addon.core.formats.imageio import read_exr, write_exr
from btf_addon.core.formats.load import load_btf


def test_info_reports_the_raw_size_and_ratio():
    out = json.loads(run_cli("info", shared_material("alu")).stdout)
    assert out["codec"] == "mlvq"
    assert out["spatial_size"] == [64, 64]
    assert out["raw_bytes"] == 80_621_568
    assert out["quantised_ratio_reported"] == pytest.approx(1002.008)
    assert out["compression_ratio"] == pytest.approx(out["raw_bytes"] / out["bytes_on_disk"])
    assert out["bytes_on_disk"] > 400_000  # the text tables, not the 80 kB quantised binary
    # BTFbase's tables state no physical size: unknown, said so (not a silent 10 mm)
    assert out["tile_size_mm"] is None and out["tile_size_source"] == "unknown"


def test_info_shows_a_stated_tile_size_and_its_origin(tmp_path):
    run_cli("synth", "woven", "-o", tmp_path / "w.btfm")
    out = json.loads(run_cli("info", tmp_path / "w.btfm").stdout)
    assert out["tile_size_mm"] == [4.0, 4.0] and out["tile_size_source"] == "synthetic"


def test_eval_matches_the_library_and_raw_units(tmp_path, rng):
    q = np.column_stack(
        [
            rng.random(500),
            rng.random(500),
            rng.random(500) * 90,
            rng.random(500) * 360,
            rng.random(500) * 90,
            rng.random(500) * 360,
        ]
    ).astype(np.float32)
    np.save(tmp_path / "q.npy", q)
    material = shared_material("wallpaper")
    run_cli("eval", material, "--queries", tmp_path / "q.npy", "--out", tmp_path / "v.npy")
    run_cli(
        "eval",
        material,
        "--queries",
        tmp_path / "q.npy",
        "--out",
        tmp_path / "r.npy",
        "--units",
        "raw",
    )
    values, raw = np.load(tmp_path / "v.npy"), np.load(tmp_path / "r.npy")
    assert values.shape == (500, 3) and values.dtype == np.float32
    btf = load_btf(material)
    np.testing.assert_array_equal(values, btf.evaluate_angles(q))
    np.testing.assert_allclose(raw * btf.meta.value_scale, values, rtol=1e-6)


@pytest.mark.parametrize("bad", ["wrong_shape", "not_npy", "missing"])
def test_eval_rejects_bad_queries(tmp_path, bad):
    q = tmp_path / "q.npy"
    if bad == "wrong_shape":
        np.save(q, np.zeros((4, 5), np.float32))
    elif bad == "not_npy":
        q.write_text("1 2 3 4 5 6")
    proc = run_cli(
        "eval", shared_material("alu"), "--queries", q, "--out", tmp_path / "o.npy", check=False
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ") and "Traceback" not in proc.stderr
    assert not (tmp_path / "o.npy").exists()


def test_swatch_writes_exr_and_png(tmp_path):
    material = shared_material("alu")
    run_cli(
        "swatch", material, "--light", 30, 0, "--view", 0, 0, "--size", 32, "-o", tmp_path / "s.exr"
    )
    image = read_exr(tmp_path / "s.exr")
    assert image.shape == (32, 32, 3) and image.min() >= 0 and image.max() > 0
    btf = load_btf(material)
    # Pixel (row 0, col 0) is the top-left: u = 1/64, v = 1 − 1/64.
    want = btf.evaluate_angles([[1 / 64, 1 - 1 / 64, 30, 0, 0, 0]])[0]
    np.testing.assert_allclose(image[0, 0], want, rtol=1e-6)
    run_cli(
        "swatch", material, "--light", 30, 0, "--view", 0, 0, "--size", 16, "-o", tmp_path / "s.png"
    )
    assert (tmp_path / "s.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_synth_and_convert_round_trip(tmp_path, rng):
    run_cli("synth", "ggx", "--albedo", "0.8,0.6,0.4", "--roughness", 0.4, "-o", tmp_path / "g")
    btf = load_btf(tmp_path / "g.btfm")
    assert btf.meta.codec == "ggx" and btf.roughness == pytest.approx(0.4)
    run_cli("synth", "lambertian", "--albedo", 0.5, "--tabulate", "ubo", "-o", tmp_path / "l.btfm")
    assert load_btf(tmp_path / "l.btfm").meta.codec == "dense"
    run_cli("convert", shared_material("alu"), tmp_path / "alu.btfm")
    q = rng.random((200, 6)) * [1, 1, 90, 360, 90, 360]
    np.testing.assert_array_equal(
        load_btf(tmp_path / "alu.btfm").evaluate_angles(q),
        load_btf(shared_material("alu")).evaluate_angles(q),
    )


def test_synth_rejects_unknown_parameters(tmp_path):
    proc = run_cli("synth", "ggx", "--shininess", 3, "-o", tmp_path / "g", check=False)
    assert proc.returncode == 2 and "no parameter --shininess" in proc.stderr
    proc = run_cli("synth", "ggx", "--roughness", 7, "-o", tmp_path / "g", check=False)
    assert proc.returncode == 2 and "roughness must be in [0, 1]" in proc.stderr
    assert not (tmp_path / "g.btfm").exists()


def test_corrupt_container_gives_a_clear_error(tmp_path):
    run_cli("synth", "lambertian", "-o", tmp_path / "m.btfm")
    blob = (tmp_path / "m.btfm").read_bytes()
    (tmp_path / "m.btfm").write_bytes(blob[: len(blob) - 20])
    proc = run_cli("info", tmp_path / "m.btfm", check=False)
    assert proc.returncode == 2 and "truncated" in proc.stderr and "Traceback" not in proc.stderr


# --- envmap ----------------------------------------------------------------------------------


def test_envmap_writes_lights(tmp_path):
    out = tmp_path / "lights.npz"
    run_cli(
        "envmap",
        studiolights_dir() / "forest.exr",
        "--lights",
        64,
        "--seed",
        2,
        "--rotation",
        30,
        "-o",
        out,
    )
    data = np.load(out)
    assert data["direction"].shape == (64, 3) and data["radiance"].shape == (64, 3)
    assert data["pdf"].shape == (64,) and np.all(data["pdf"] > 0)
    np.testing.assert_allclose(np.linalg.norm(data["direction"], axis=1), 1.0, rtol=1e-6)


@pytest.mark.parametrize("case", ["zero", "nan", "huge", "1x1", "2x1", "odd"])
def test_envmap_hard_maps_through_the_cli(tmp_path, case):
    maps = {
        "zero": np.zeros((8, 16, 3)),
        "huge": np.full((8, 16, 3), 1e6),
        "1x1": np.ones((1, 1, 3)),
        "2x1": np.ones((2, 1, 3)),
        "odd": np.random.default_rng(1).random((5, 11, 3)),
    }
    img = maps.get(case, np.ones((8, 16, 3)))
    if case == "nan":
        img = img.copy()
        img[2, 3] = np.nan
        img[4, 5] = np.inf
    write_exr(tmp_path / "m.exr", img)
    proc = run_cli("envmap", tmp_path / "m.exr", "--lights", 32, "-o", tmp_path / "l.npz")
    data = np.load(tmp_path / "l.npz")
    for key in ("direction", "radiance", "pdf"):
        assert np.all(np.isfinite(data[key]))
    if case == "nan":
        assert "2 NaN/Inf pixels" in proc.stdout


def test_envmap_rejects_a_non_exr(tmp_path):
    (tmp_path / "m.exr").write_text("not an image")
    proc = run_cli("envmap", tmp_path / "m.exr", "-o", tmp_path / "l.npz", check=False)
    assert proc.returncode == 2 and "not a readable OpenEXR" in proc.stderr
    assert not (tmp_path / "l.npz").exists()


def test_eval_opencl_backend_matches_numpy(tmp_path, rng):
    q = (rng.random((3000, 6)) * [1, 1, 90, 360, 90, 360]).astype(np.float32)
    np.save(tmp_path / "q.npy", q)
    material = shared_material("alu")
    run_cli(
        "eval",
        material,
        "--queries",
        tmp_path / "q.npy",
        "--out",
        tmp_path / "cl.npy",
        "--backend",
        "opencl",
    )
    run_cli("eval", material, "--queries", tmp_path / "q.npy", "--out", tmp_path / "np.npy")
    got, want = np.load(tmp_path / "cl.npy"), np.load(tmp_path / "np.npy")
    np.testing.assert_allclose(got, want, rtol=2e-3, atol=2e-4 * float(want.max()))


def test_eval_opencl_without_opencl_is_a_clear_error(tmp_path):

    np.save(tmp_path / "q.npy", np.zeros((4, 6), np.float32))
    env = cli_env(OCL_ICD_VENDORS=str(tmp_path / "none"), OCL_ICD_FILENAMES="")
    proc = run_cli(
        "eval",
        shared_material("alu"),
        "--queries",
        tmp_path / "q.npy",
        "--out",
        tmp_path / "o.npy",
        "--backend",
        "opencl",
        check=False,
        env=env,
    )
    assert proc.returncode == 2
    assert "OpenCL back end unavailable" in proc.stderr and "pocl" in proc.stderr
    assert "Traceback" not in proc.stderr and not (tmp_path / "o.npy").exists()


def test_raw_units_of_a_ubo2014_file_are_its_stored_rgb(tmp_path):
    """A UBO2014 file whose data lacks the cosine (meta version 1: no cosine flag, so 0): the
    value is RGB · scale / π · cos θi, and ``--units raw`` gives the stored RGB · scale back
    unchanged — computed here by hand from the file's own factors (btflib: the cosine flag
    says whether the data holds the cosine; raw must not depend on it). rtol 1e-5: float32
    factors and output."""
    from ubo2014_files import YUV_TO_RGB, hand_built

    blob, src = hand_built(version=1)
    path = tmp_path / "nocos.btf"
    path.write_bytes(blob)
    rows, want = [], []
    for v, (tv, pv) in enumerate(src["views"]):
        for li, (tl, pl) in enumerate(src["lights"]):
            row = v * len(src["lights"]) + li
            for x in (0, 1):
                y = [float(src["u"][c][row] @ src["sv"][c][x]) for c in range(3)]
                want.append(np.maximum(YUV_TO_RGB @ np.array(y) * (1.0, 0.5, 2.0), 0.0))
                rows.append([(x + 0.5) / 2, 0.5, *np.degrees([tl, pl, tv, pv])])
    np.save(tmp_path / "q.npy", np.array(rows, np.float32))
    for units in ("value", "raw"):
        run_cli(
            "eval",
            path,
            "--queries",
            tmp_path / "q.npy",
            "--out",
            tmp_path / f"{units}.npy",
            "--units",
            units,
        )
    raw, value = np.load(tmp_path / "raw.npy"), np.load(tmp_path / "value.npy")
    np.testing.assert_allclose(raw, np.array(want), rtol=1e-5, atol=1e-6)
    cos_i = np.cos(np.radians(np.array(rows)[:, 2]))[:, None]
    np.testing.assert_allclose(value, np.array(want) * cos_i / np.pi, rtol=1e-5, atol=1e-7)

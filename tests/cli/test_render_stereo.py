"""``render --stereo PROFILE``: stereo captures of the demo scene and a saved .blend, headless
through the CLI (the eyes' pixels against independent matrices: tests/gl/test_stereo_capture.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import make_blend, read_png, run_cli

from btf_addon.core.formats.imageio import read_exr, srgb8_from_linear

ARGS = ("render", "--demo", "--stereo", "simulated", "--eye-width", "48", "--lights", "8")


@pytest.fixture(scope="module")
def exr_capture(tmp_path_factory):
    folder = tmp_path_factory.mktemp("stereo")
    proc = run_cli(*ARGS, "-o", folder / "pair.exr", cwd=folder)
    return folder, proc


def test_side_by_side_exr_and_its_json(exr_capture):
    folder, proc = exr_capture
    assert "captured simulated: 2 × 48×36" in proc.stdout and "8 virtual lights" in proc.stdout
    assert sorted(p.name for p in folder.glob("pair*")) == ["pair.exr", "pair.json"]
    image = read_exr(folder / "pair.exr")
    assert image.shape == (36, 96, 3) and np.isfinite(image).all()
    left, right = image[:, :48], image[:, 48:]
    assert left.max() > 0.05 and np.abs(left - right).max() > 0.01  # two different views
    meta = json.loads((folder / "pair.json").read_text())
    assert meta["profile"]["name"] == "simulated" and meta["ipd_m"] == 0.063
    assert meta["layout"] == "side-by-side" and meta["eye_size"] == [48, 36]
    assert meta["lights"] == {"count": 8, "lighting": "environment", "seed": 0}
    assert meta["eyes"]["right"]["fov_rad"] == {
        "angle_left": -0.74,
        "angle_right": 0.74,
        "angle_up": 0.78,
        "angle_down": -0.78,
    }
    left_pose, right_pose = (np.array(meta["eyes"][e]["world_from_eye"]) for e in meta["eyes"])
    # Same orientation; the right eye 63 mm along the eyes' shared +x from the left one.
    np.testing.assert_allclose(left_pose[:3, :3], right_pose[:3, :3], atol=1e-12)
    baseline = right_pose[:3, 3] - left_pose[:3, 3]
    np.testing.assert_allclose(baseline, 0.063 * left_pose[:3, 0], atol=1e-9)


def test_per_eye_png_through_the_scenes_colour_management(exr_capture):
    """The demo's Standard view without dither: each PNG is the sRGB curve of its eye. As in
    test_render_command: Blender's OpenColorIO may round a value within 1/255 of a code
    boundary the other way, so at most 1 code apart, on under 1 % of the pixels."""
    folder, _ = exr_capture
    proc = run_cli(*ARGS, "--layout", "per-eye", "-o", folder / "eyes.png", cwd=folder)
    names = ("eyes_left.png", "eyes_right.png", "eyes.json")
    assert all(str(folder / n) in proc.stdout for n in names)
    linear = read_exr(folder / "pair.exr")  # the same scene, lights and eyes
    for name, half in (("left", linear[:, :48]), ("right", linear[:, 48:])):
        png = read_png(folder / f"eyes_{name}.png")
        assert png.shape[:2] == (36, 48)
        diff = np.abs(png[..., :3].astype(int) - srgb8_from_linear(half).astype(int))
        assert diff.max() <= 1 and (diff > 0).mean() < 0.01, name
    assert json.loads((folder / "eyes.json").read_text())["image_size"] is None


def test_a_saved_blend_with_headlight(tmp_path):
    """--blend takes the same path: the file's camera is the head; --lighting overrides the
    scene's settings (one headlight, recorded in the JSON)."""
    blend = tmp_path / "plane.blend"
    make_blend(
        blend,
        """
        bpy.ops.mesh.primitive_plane_add(size=4.0)
        bpy.ops.object.camera_add(location=(0.0, 0.0, 3.0))
        scene.camera = bpy.context.object
        """,
    )
    out = tmp_path / "plane.exr"
    run_cli(
        "render", "--blend", blend, "--stereo", "generic-2016x2240", "--eye-width", "36",
        "--lighting", "headlight", "-o", out,
    )  # fmt: skip
    image = read_exr(out)
    assert image.shape == (40, 72, 3)  # 2016×2240 scaled to 36 wide: 40 high
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["lights"]["count"] == 1 and meta["lights"]["lighting"] == "headlight"
    # The plane fills the view's centre: lit there (Blender's default grey material).
    assert image[20, 18].min() > 0.05 and image[20, 54].min() > 0.05


def test_stereo_errors_are_clear(tmp_path):
    blend = tmp_path / "nocam.blend"
    make_blend(blend, "bpy.ops.mesh.primitive_cube_add()\n")
    proc = run_cli(
        "render", "--blend", blend, "--stereo", "simulated", "-o", tmp_path / "x.exr", check=False
    )
    assert proc.returncode == 2 and "no camera to capture from" in proc.stderr
    for args, message in (
        (["--stereo", "nosuch"], "invalid choice: 'nosuch'"),
        (["--stereo", "xtal-8k", "--eye-width", "20000"], "larger than the drawer's 16384"),
        (["--stereo", "xtal-8k", "--eye-width", "0"], "at least 1 pixel"),
        (["--layout", "per-eye"], "--layout needs --stereo PROFILE"),
        (["--stereo", "simulated", "--layout", "top-bottom"], "invalid choice: 'top-bottom'"),
        (["--stereo", "simulated", "--resolution", "64x64"], "--resolution (use --eye-width)"),
        (["--stereo", "simulated", "--samples", "4"], "F12 only"),
    ):
        proc = run_cli("render", "--demo", "-o", tmp_path / "x.exr", *args, check=False)
        assert proc.returncode == 2 and message in proc.stderr, proc.stderr
        assert "Traceback" not in proc.stderr
    assert not list(tmp_path.glob("x*"))

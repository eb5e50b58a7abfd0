"""``accuracy``: the quality-vs-time report of a small .blend, through the CLI."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import numpy as np
from helpers import ROOT, cli_env, make_blend, read_png, run_cli

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container
from btf_addon.core.formats.imageio import read_exr
from btf_addon.render.accuracy.ladder import relative_rmse

#: A Lambertian sphere on a Lambertian ground under the forest studiolight, 64×48: shadows and
#: interreflection exist, so every knob (lights, samples, bounces) changes the image.
SCENE = """
from helpers import studiolights_dir
bpy.ops.mesh.primitive_plane_add(size=6.0)
ground = bpy.context.object
bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, location=(0, 0, 1.0), segments=24, ring_count=12)
sphere = bpy.context.object
bpy.ops.object.shade_smooth()
material = with_nodes(bpy.data.materials.new("Lambert"))
material.btf.enabled = True
material.btf.source = "//lambert.btfm"
for obj in (ground, sphere):
    obj.data.materials.append(material)
cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
scene.collection.objects.link(cam)
cam.location = (0.0, -6.0, 3.0)
cam.rotation_euler = (1.2, 0.0, 0.0)
scene.camera = cam
world = with_nodes(bpy.data.worlds.new("W"))
texture = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
texture.image = bpy.data.images.load(str(studiolights_dir() / "forest.exr"))
background = world.node_tree.nodes["Background"]
world.node_tree.links.new(texture.outputs["Color"], background.inputs["Color"])
scene.world = world
scene.render.engine = "BTF_RENDER"
scene.render.resolution_x, scene.render.resolution_y = 64, 48
scene.render.resolution_percentage = 100
scene.btf_render.lights_total = 64
scene.btf_render.samples = 16
scene.btf_render.max_bounces = 2
"""


def make_scene(folder, extra: str = ""):
    write_container(folder / "lambert.btfm", LambertianBTF(0.7))
    blend = folder / "scene.blend"
    path = f"import sys\nsys.path.insert(0, {str(ROOT / 'tests')!r})\n"
    make_blend(blend, path + SCENE + extra)
    return blend


def test_accuracy_report_of_a_small_scene(tmp_path):
    """The whole command on a 64×48 scene at 24×18 with a 256-sample reference (about 10 s):
    every rung scored, a recommendation that meets the budget, the report's files."""
    blend = make_scene(tmp_path)
    out = tmp_path / "report"
    proc = run_cli(
        "accuracy",
        "--blend",
        blend,
        "-o",
        out,
        "--size",
        "24",
        "--reference-samples",
        "256",
        "--budget",
        "60",
    )
    assert "recommended: " in proc.stdout and "at 64x48" in proc.stdout
    data = json.loads((out / "report.json").read_text())
    assert data["preview_size"] == [24, 18] and data["full_size"] == [64, 48]
    # 24: lights 5 + samples 5 + bounces 3, anti-aliasing off and the other texel filter per
    # final mode (4), 1 and 4 subpixels beside the default 16 for Virtual Lights (2), Clamp
    # Indirect off beside the default 10, 1 sample per camera ray beside 4, adaptive sampling
    # off and Noise Thresholds 0.005 and 0.05 beside 0.01 for Sampled (5).
    assert data["rungs_done"] == data["rungs_total"] == 24 and not data["interrupted"]
    errors = {(p["series"], tuple(p["knobs"].values())): p["rmse"] for p in data["points"]}
    # Knobs do what they should against the reference: more samples → less error (1 → 64:
    # noise falls 8×; the reference's own noise is under a third of the 64-sample rung's);
    # no bounces misses the light sphere and ground exchange.
    s = {k[1][1]: e for k, e in errors.items() if k[0] == "sampled: Samples"}
    assert s[1] > s[4] > s[16] > s[64]
    b = {k[1][2]: e for k, e in errors.items() if k[0] == "sampled: Max Bounces"}
    assert b[0] > s[16]
    rec = data["recommendation"]
    assert rec["met"] and rec["predicted_seconds"] <= 60
    # The most accurate rung within the budget: every rung fits 60 s here.
    assert rec["rmse"] == min(p["rmse"] for p in data["points"])
    assert data["reference"]["noise_rmse"] is not None
    for name in ("error_vs_time.png", "ssim_vs_time.png", "heat_recommended.png"):
        assert read_png(out / name).shape[2] == 3
    ref = read_png(out / "reference.png")
    assert ref.shape == (18, 24, 3) and np.ptp(ref) > 50  # a lit image, not black
    assert "<table" in (out / "report.html").read_text()

    # The recommendation rendered at full size by `render --blend` lands within its stated
    # error against a full-size reference of the report's reference settings. Margin 1.5×:
    # the full-size error is measured on 7× the pixels, with its own reference noise.
    def render(settings, path):
        flags = {
            "final_mode": "--final-mode",
            "lights_total": "--lights",
            "samples": "--samples",
            "max_bounces": "--bounces",
            "seed": "--seed",
        }
        args = [a for name, flag in flags.items() for a in (flag, str(settings[name]).lower())]
        adaptive = settings["use_adaptive_sampling"] and settings["adaptive_threshold"]
        args += ["--noise-threshold", str(adaptive or 0)]  # 0: off, as the reference
        run_cli("render", "--blend", blend, "-o", path, *args)
        return read_exr(path)

    reference = render(data["reference"]["settings"], tmp_path / "ref.exr")
    image = render(rec["settings"], tmp_path / "rec.exr")
    full_error = relative_rmse(image, reference)
    assert full_error <= 1.5 * rec["rmse"], (full_error, rec["rmse"])


def test_accuracy_with_the_light_bake_measures_its_knobs(tmp_path):
    """``--bake``: after the ladder, one bake per bake knob (from the scene's own: coarse here,
    0.5 m, 2 × 2 views, 16 samples) scored against the same reference; the baked drawer of
    this Lambertian scene (contact shadow, bounce) is within a few % of F12, and the knobs
    move error, time and memory as they should."""
    bake = "scene.btf_bake.spacing, scene.btf_bake.view_bins, scene.btf_bake.samples = 0.5, 2, 16"
    blend = make_scene(tmp_path, bake)
    out = tmp_path / "report"
    run_cli(
        "accuracy", "--blend", blend, "-o", out, "--quick", "--size", "24",
        "--reference-samples", "256", "--bake",
    )  # fmt: skip
    rows = json.loads((out / "report.json").read_text())["bake"]
    assert [(r["knob"], r["spacing"], r["view_bins"]) for r in rows] == [
        ("scene's own", 0.5, 2),
        ("spacing", 1.0, 2),
        ("spacing", 2.0, 2),
        ("view directions", 0.5, 3),
        ("view directions", 0.5, 5),
        ("view directions", 0.5, 7),
    ]
    assert all(r["objects"] == 2 and r["seconds"] > 0 for r in rows)  # sphere on its ground
    own = rows[0]
    # Lambertian: the light per point does not depend on the view, so the error is the
    # spacing's interpolation and the bake's and reference's noise (16 and 256 samples).
    # Measured on this 24 × 18 preview (seeded: the same run gives the same numbers): 4.1 %
    # at 0.5 m, 4.9 % at 1 m, 6.0 % at 2 m, 3.8-4.3 % for 3-7 views (the view does not matter
    # to a Lambertian surface); 0.1 leaves room for another device's rounding.
    assert own["rmse"] < 0.1, own
    assert rows[2]["rmse"] > own["rmse"]  # 2 m between points blurs the contact shadow
    assert rows[2]["gpu_mib"] < rows[1]["gpu_mib"] < own["gpu_mib"]  # fewer points
    assert rows[5]["gpu_mib"] > rows[4]["gpu_mib"] > rows[3]["gpu_mib"] > own["gpu_mib"]
    assert "## Light bake for VR" in (out / "report.md").read_text()


def test_accuracy_errors_are_clear(tmp_path):
    proc = run_cli("accuracy", "--blend", tmp_path / "none.blend", check=False)
    assert proc.returncode == 2 and "no such .blend" in proc.stderr
    blend = tmp_path / "head.blend"
    make_blend(
        blend,
        """
        cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
        scene.collection.objects.link(cam)
        scene.camera = cam
        scene.btf_render.lighting = "HEADLIGHT"
        """,
    )
    proc = run_cli("accuracy", "--blend", blend, "-o", tmp_path / "r", check=False)
    assert proc.returncode == 2 and "headlight" in proc.stderr and "Traceback" not in proc.stderr
    proc = run_cli("accuracy", "--blend", blend, "--budget", "-1", check=False)
    assert proc.returncode == 2 and "must be > 0" in proc.stderr


def test_ctrl_c_keeps_what_is_done(tmp_path):
    """SIGINT once the first rungs are in report.json: the command writes the report of what
    it has (marked interrupted), recommends from it, and exits with 130."""
    blend = make_scene(tmp_path)
    out = tmp_path / "report"
    # At the full 64×48 the ladder takes several seconds after its first rung: time to
    # interrupt it part-way.
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "btf_addon",
            "accuracy",
            "--blend",
            str(blend),
            "-o",
            str(out),
            "--size",
            "64",
            "--reference-samples",
            "64",
        ],
        cwd=ROOT,
        env=cli_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None:
            report = out / "report.json"
            if report.is_file() and json.loads(report.read_text())["rungs_done"] >= 1:
                break
            time.sleep(0.02)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        proc.kill()
    data = json.loads((out / "report.json").read_text())
    assert proc.returncode == 130, stderr
    assert data["interrupted"] and 1 <= data["rungs_done"] < data["rungs_total"]
    assert "interrupted" in stderr and "recommended: " in stdout
    assert "Interrupted" in (out / "report.md").read_text()

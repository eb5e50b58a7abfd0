"""Estimate Quality vs Time in Blender: the operator (scripted: it runs to the end), its worker
job's cancel, the panel's plot preview and Apply Recommended."""

from __future__ import annotations

import json

import numpy as np
from blender_helpers import draw_panel, extension_submodule, sphere_on_ground

from btf_addon.core.codecs.analytic import LambertianBTF
from btf_addon.core.formats.container import write_container


def _small_scene(bpy, tmp_path):
    """The tests' sphere on ground at 48×32; the estimate at 16 pixels wide with a 32-sample
    reference (about 2 s of rendering on PoCL)."""
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (48, 32), 16, 8)
    scene.btf_accuracy.thoroughness = "FULL"
    scene.btf_accuracy.preview_size = 16
    scene.btf_accuracy.reference_samples = 32
    scene.btf_accuracy.budget = 30.0
    return scene


def test_the_quick_estimate_is_the_default_and_speaks_in_words(bpy_module, fresh_scene, tmp_path):
    """Issue 32 item 4: the default estimate measures only the scene's own mode's work knob
    (the samples or lights a designer trades against time) on a small preview, and the panel
    says the result in words: no "rung", no "rmse", no ``texel_filter=LINEAR``."""

    bpy = bpy_module
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (48, 32), 16, 8)
    scene.btf_accuracy.target = 0.001  # unreachable here: the panel says what would reach it
    scene.btf_render.final_mode = "SAMPLED"
    assert scene.btf_accuracy.thoroughness == "QUICK"
    assert bpy.ops.btf.estimate_quality() == {"FINISHED"}
    data = json.loads(scene.btf_accuracy.report)
    ladder = extension_submodule("btf_addon.render.accuracy.ladder")
    own = scene.btf_render.samples
    expected = sorted({*ladder.QUICK_VALUES["samples"], own})
    assert [p["knobs"]["samples"] for p in data["points"]] == expected
    base = {k: v for k, v in data["points"][0]["knobs"].items() if k != "samples"}
    assert all({k: v for k, v in p["knobs"].items() if k != "samples"} == base
               for p in data["points"])  # fmt: skip
    run = extension_submodule("btf_addon.blender.accuracy.run")
    assert data["reference"]["settings"]["samples"] == run.QuickSizes.reference_samples
    rec = data["recommendation"]
    assert rec["words"].startswith(f"{rec['knobs']['samples']} samples: noise ")
    assert rec["words"].endswith("at full size (48×32)")
    assert not rec["met"] and "samples would" in rec["reason_words"]

    module = extension_submodule("btf_addon.blender.accuracy.operator")
    labels = draw_panel(module.BTF_PT_render_accuracy, bpy.context).labels
    shown = " ".join(labels)
    assert f"Recommended: {rec['words']}" in labels and rec["reason_words"] in labels
    for jargon in ("rung", "rmse", "RMSE", "texel_filter", "="):
        assert jargon not in shown, (jargon, labels)


def test_include_light_bake_measures_the_bakes_knobs(bpy_module, fresh_scene, tmp_path):
    """The quick estimate with Include Light Bake: the bake's rungs from the scene's own Light
    Bake for VR knobs (coarse here: 0.5 apart, 2 × 2 views, 16 samples), each scored, and the
    panel lists them in words (the CLI's ``--bake`` runs the same sweep:
    tests/cli/test_accuracy_command.py holds its numbers)."""
    bpy = bpy_module
    write_container(tmp_path / "lambert.btfm", LambertianBTF(0.7))
    scene = sphere_on_ground(bpy, tmp_path, tmp_path / "lambert.btfm", (48, 32), 16, 8)
    scene.btf_bake.spacing, scene.btf_bake.view_bins, scene.btf_bake.samples = 0.5, 2, 16
    scene.btf_accuracy.include_bake = True
    assert bpy.ops.btf.estimate_quality() == {"FINISHED"}
    rows = json.loads(scene.btf_accuracy.report)["bake"]
    assert [(r["knob"], r["view_bins"]) for r in rows][:2] == [("scene's own", 2), ("spacing", 2)]
    assert len(rows) == 6 and all(r["objects"] == 2 and r["rmse"] < 0.2 for r in rows)
    module = extension_submodule("btf_addon.blender.accuracy.operator")
    labels = draw_panel(module.BTF_PT_render_accuracy, bpy.context).labels
    assert "Bake 0.5 apart, 2×2 views, 16 samples: " in " ".join(labels)


def test_estimate_stores_a_report_and_apply_recommended_sets_it(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    scene = _small_scene(bpy, tmp_path)
    assert bpy.ops.btf.estimate_quality() == {"FINISHED"}
    data = json.loads(scene.btf_accuracy.report)
    assert data["preview_size"] == [16, 11] and data["full_size"] == [48, 32]
    # 25 rungs: the scene's own 24 lights join the lights sweep (4, 16, 24, 64, 256, 1024);
    # per final mode anti-aliasing off and the other texel filter, for Virtual Lights 1 and 4
    # anti-aliasing subpixels beside the scene's 16, for Sampled Clamp Indirect off beside 10,
    # 1 sample per camera ray beside 4, adaptive sampling off, and Noise Thresholds 0.005 and
    # 0.05 beside 0.01.
    assert data["rungs_done"] == data["rungs_total"] == 25 and data["budget_seconds"] == 30.0
    rec = data["recommendation"]
    assert rec is not None and rec["predicted_seconds"] <= 30.0
    assert rec["rmse"] == min(p["rmse"] for p in data["points"])  # everything fits 30 s here

    # The panel's curve: an image preview of the plot raster, rows bottom first.
    module = extension_submodule("btf_addon.blender.accuracy.operator")
    report = extension_submodule("btf_addon.render.accuracy.report")
    preview = module.plot_preview(scene)
    w, h = module.PLOT_SIZE
    assert tuple(preview.image_size) == (w, h)
    pixels = np.array(preview.image_pixels_float[:]).reshape(h, w, 4)
    expected = report.error_plot(data, "rmse", module.PLOT_SIZE)
    # 8-bit values through float: equal to float32 rounding.
    np.testing.assert_allclose(pixels[::-1, :, :3] * 255, expected, atol=1e-3)

    seed = scene.btf_render.seed
    assert bpy.ops.btf.apply_recommended() == {"FINISHED"}
    for name, value in rec["knobs"].items():
        if name == "texel_filter":  # a material knob: every BTF material's
            btf_materials = [m for m in bpy.data.materials if m.btf.enabled]
            assert btf_materials and all(m.btf.texel_filter == value for m in btf_materials)
        else:
            assert getattr(scene.btf_render, name) == value, name
    assert scene.btf_render.seed == seed  # only the knobs change
    # One undo step: Blender pushes one for an operator with UNDO when it finishes
    # (background Blender has no window, so ed.undo itself cannot run here).
    assert {"REGISTER", "UNDO"} <= module.BTF_OT_apply_recommended.bl_options
    assert "UNDO" not in module.BTF_OT_estimate_quality.bl_options


def test_cancel_keeps_what_is_done_and_headlight_is_refused(bpy_module, fresh_scene, tmp_path):
    bpy = bpy_module
    scene = _small_scene(bpy, tmp_path)
    module = extension_submodule("btf_addon.blender.accuracy.operator")
    job = module.start_job(bpy.context)
    assert module.running_job(scene) is job
    # Cancel once two rungs are in (the worker checks between launches).
    while len(job.estimate.points) < 2 and not job.done.is_set():
        job.done.wait(0.01)
    job.cancel.set()
    assert job.done.wait(60)
    assert job.estimate.interrupted and 2 <= len(job.estimate.points) < 14
    data = json.loads(job.report_json())
    assert data["interrupted"] and data["rungs_done"] == len(job.estimate.points)
    module._jobs.clear()

    scene.btf_render.lighting = "HEADLIGHT"
    try:
        bpy.ops.btf.estimate_quality()
        raised = ""
    except RuntimeError as exc:
        raised = str(exc)
    assert "headlight" in raised


class RecordingLayout:
    """Stands in for a panel's UILayout (none exists headless): records what draw() asks."""

    def __init__(self, calls=None):
        self.calls = [] if calls is None else calls
        self.use_property_split = False

    def __getattr__(self, name):
        def record(*args, **kwargs):
            self.calls.append((name, args, kwargs))
            return RecordingLayout(self.calls)

        return record


def test_panel_draws_the_report_the_progress_and_the_buttons(bpy_module, fresh_scene, tmp_path):
    from types import SimpleNamespace

    bpy = bpy_module
    scene = _small_scene(bpy, tmp_path)
    module = extension_submodule("btf_addon.blender.accuracy.operator")
    panel = module.BTF_PT_render_accuracy

    def draw():
        layout = RecordingLayout()
        panel.draw(SimpleNamespace(layout=layout), SimpleNamespace(scene=scene))
        return layout.calls

    calls = draw()  # no report yet: the settings and the button only
    assert ("operator", ("btf.estimate_quality",), {"icon": "TIME"}) in calls
    assert not any(c[0] == "template_icon" for c in calls)
    assert bpy.ops.btf.estimate_quality() == {"FINISHED"}
    calls = draw()
    icons = [c for c in calls if c[0] == "template_icon"]
    assert len(icons) == 1 and icons[0][2]["icon_value"] == module.plot_preview(scene).icon_id
    labels = [c[2].get("text", "") for c in calls if c[0] == "label"]
    assert any(t.startswith("Recommended: ") for t in labels)
    assert any(c[0] == "operator" and c[1] == ("btf.apply_recommended",) for c in calls)
    # While a job runs: its progress and the cancel button instead of the estimate button.
    job = SimpleNamespace(
        fraction=0.25, text="samples=16", done=SimpleNamespace(is_set=lambda: False)
    )
    module._jobs[scene.as_pointer()] = job
    try:
        calls = draw()
    finally:
        module._jobs.clear()
    assert any(c[0] == "progress" and c[2]["factor"] == 0.25 for c in calls)
    assert any(c[0] == "operator" and c[1] == ("btf.estimate_quality_cancel",) for c in calls)
    assert not any(c[0] == "operator" and c[1] == ("btf.estimate_quality",) for c in calls)

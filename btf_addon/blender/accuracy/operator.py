"""Estimate Quality vs Time: the accuracy report inside Blender (Render Properties > BTF >
Quality vs Time).

The operator exports the scene at the preview size on the main thread (bpy), then renders the
ladder on a worker thread (bpy-free: blender/accuracy/run.py + render/accuracy/ladder.py) while a
modal timer shows progress; Esc or the panel's Cancel stops it between launches, keeping the
rungs done. Run from a script (``bpy.ops.btf.estimate_quality()``, no window), it runs to the
end before returning. The result is stored on the scene as the report's JSON
(``scene.btf_accuracy.report``, saved with the file); the panel draws its curve as an image
preview made by the numpy plot raster (render/accuracy/plot.py) and offers Apply Recommended,
one undo step.
"""

from __future__ import annotations

import json
import logging
import threading

import bpy
import numpy as np
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)
from bpy.types import Operator, Panel, PropertyGroup

from ...render.accuracy.bake_sweep import row_words
from ...render.accuracy.ladder import run, settings_from_json, verify_recommendation
from ...render.accuracy.report import error_plot, to_json
from ...render.settings import RenderSettings
from ..addon import ENGINE_ID
from ..background_job import PanelJobModal, progress_row, running_in, stop_all
from ..bake.run import knobs_for
from ..preferences import preferred_device
from ..sync import render_settings
from .run import QuickSizes, prepare, run_bake_sweep, set_up

log = logging.getLogger(__name__)

#: The panel's plot: square-ish and small enough to upload on every new report.
PLOT_SIZE = (320, 240)


class BTFAccuracySettings(PropertyGroup):
    budget: FloatProperty(
        name="Time Budget",
        default=0.0,
        min=0.0,
        unit="TIME_ABSOLUTE",
        description="Seconds one full-resolution render may take (0: no budget)",
    )
    target: FloatProperty(
        name="Target Error",
        default=0.02,
        min=0.0,
        max=1.0,
        precision=3,
        description="Relative RMSE against the reference to reach (0: none)",
    )
    thoroughness: EnumProperty(
        name="Estimate",
        items=(
            ("QUICK", "Quick", "The scene's own mode, its samples or lights only, at a small "
             "preview: about a minute on two CPU cores for 320×240", 0),
            ("FULL", "Full", "Every quality knob (mode, samples or lights, bounces, "
             "anti-aliasing, texel filter) at Preview Size against Reference Samples", 1),
        ),
        default="QUICK",
    )  # fmt: skip
    preview_size: IntProperty(
        name="Preview Size",
        default=160,
        min=8,
        max=2048,
        description="Longest side, in pixels, of the reduced renders the estimate measures",
    )
    reference_samples: IntProperty(
        name="Reference Samples",
        default=1024,
        min=1,
        max=65536,
        description="Samples per pixel of the reference (the World sampled, 8 bounces)",
    )
    include_bake: BoolProperty(
        name="Include Light Bake",
        default=False,
        description="Also measure the light bake's knobs (spacing, view directions, samples: one "
        "bake each, minutes on a CPU): error against the reference, bake time, GPU memory",
    )
    report: StringProperty(
        name="Report",
        default="",
        options={"HIDDEN"},
        description="The last estimate, as the CLI's report.json",
    )

    @classmethod
    def register(cls) -> None:
        bpy.types.Scene.btf_accuracy = PointerProperty(type=cls, name="BTF Quality vs Time")

    @classmethod
    def unregister(cls) -> None:
        del bpy.types.Scene.btf_accuracy


class Job:
    """One estimate on a worker thread. The thread touches no bpy data: it reads and writes
    only this object (progress, the estimate), which the modal timer copies into the UI."""

    def __init__(self, estimate, rungs, renderer, budget, target, bake_knobs=None):
        self.estimate, self.rungs, self.renderer = estimate, rungs, renderer
        self.budget, self.target = budget, target
        self.bake_knobs = bake_knobs  # None: no light bake sweep
        self.cancel = threading.Event()
        self.fraction, self.text = 0.0, "starting"
        self.error: BaseException | None = None
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._work, name="btf-accuracy", daemon=True)

    def _progress(self, fraction: float, text: str) -> None:
        self.fraction, self.text = fraction, text

    def _work(self) -> None:
        try:
            self._progress(0.0, "opening the OpenCL device, loading the kernels")
            set_up(self.estimate, self.renderer)
            run(
                self.estimate,
                self.rungs,
                self.renderer,
                on_progress=self._progress,
                cancelled=self.cancel.is_set,
            )
            if not self.estimate.interrupted:
                self._progress(1.0, "verifying the recommendation")
                verify_recommendation(
                    self.estimate,
                    self.renderer,
                    self.budget,
                    self.target,
                    cancelled=self.cancel.is_set,
                )
            if self.bake_knobs is not None and not self.cancel.is_set():
                run_bake_sweep(
                    self.estimate,
                    self.renderer,
                    self.bake_knobs,
                    on_progress=self._progress,
                    cancelled=self.cancel.is_set,
                )
        except Exception as exc:  # shown by the operator on the main thread
            log.exception("quality estimate failed")
            self.error = exc
        finally:
            self.done.set()

    def report_json(self) -> str:
        return json.dumps(to_json(self.estimate, self.budget, self.target), allow_nan=False)


#: The running job per scene (by its session pointer), so the panel can show and cancel it.
_jobs: dict[int, Job] = {}


def running_job(scene) -> Job | None:
    return running_in(_jobs, scene)


def start_job(context) -> Job:
    """Export and prepare on this (main) thread, then start the worker."""
    scene = context.scene
    props = scene.btf_accuracy
    quick = props.thoroughness == "QUICK"
    estimate, rungs, renderer = prepare(
        context.evaluated_depsgraph_get(),
        QuickSizes.longest if quick else props.preview_size,
        preferred_device(),
        QuickSizes.reference_samples if quick else props.reference_samples,
        QuickSizes.reference_bounces if quick else 8,
        setup=False,  # on the worker: a first kernel compile must not freeze the UI
        quick=quick,
    )
    bake, bake_knobs = scene.btf_bake, None  # the bake's own knobs, as Bake Light for VR's
    if props.include_bake:
        bake_knobs = knobs_for(scene, bake.spacing, bake.view_bins, bake.samples)
    job = Job(
        estimate,
        rungs,
        renderer,
        props.budget if props.budget > 0 else None,
        props.target if props.target > 0 else None,
        bake_knobs,
    )
    _jobs[scene.as_pointer()] = job
    job.thread.start()
    return job


def finish_job(operator, context, job: Job) -> set[str]:
    """On the main thread after the worker ended: store the report, say what happened."""
    _jobs.pop(context.scene.as_pointer(), None)
    if job.error is not None:
        operator.report({"ERROR"}, f"Quality estimate failed: {job.error}")
        return {"CANCELLED"}
    context.scene.btf_accuracy.report = job.report_json()
    est = job.estimate
    data = json.loads(context.scene.btf_accuracy.report)
    rec = data["recommendation"]
    done = f"{len(est.points)} of {len(job.rungs)} settings measured"
    if rec is None:
        operator.report({"WARNING"}, f"Quality estimate cancelled: {done}")
        return {"CANCELLED"}
    operator.report(
        {"INFO"},
        f"{done}: recommended {rec['words']}" + (" (cancelled early)" if est.interrupted else ""),
    )
    return {"FINISHED"}


class BTF_OT_estimate_quality(PanelJobModal, Operator):
    """Measure error against render time for this scene's quality settings (virtual lights,
    samples, bounces) at a reduced size, and recommend settings for a time budget or a
    target error"""

    bl_idname = "btf.estimate_quality"
    bl_label = "Estimate Quality vs Time"
    bl_options = {"REGISTER"}  # stores a report, changes no render setting: no undo step
    status_label = "Quality vs Time"

    @classmethod
    def poll(cls, context) -> bool:
        scene = context.scene
        return scene is not None and scene.render.engine == ENGINE_ID and not running_job(scene)

    def _begin(self, context) -> Job:
        return start_job(context)

    def _finish(self, context, job: Job) -> set[str]:
        return finish_job(self, context, job)


class BTF_OT_estimate_quality_cancel(Operator):
    """Stop the running estimate after the current launch, keeping the settings measured"""

    bl_idname = "btf.estimate_quality_cancel"
    bl_label = "Cancel Estimate"
    bl_options = {"INTERNAL"}

    def execute(self, context) -> set[str]:
        job = running_job(context.scene)
        if job is not None:
            job.cancel.set()
        return {"FINISHED"}


def recommended_settings(scene) -> RenderSettings | None:
    """The scene's settings with the stored recommendation's knobs applied (None: no report
    or no recommendation)."""
    text = scene.btf_accuracy.report
    if not text:
        return None
    rec = json.loads(text).get("recommendation")
    if rec is None:
        return None
    current = render_settings(scene)
    return settings_from_json(rec["knobs"], current)


class BTF_OT_apply_recommended(Operator):
    """Set the render settings to the recommended ones (one undo step)"""

    bl_idname = "btf.apply_recommended"
    bl_label = "Apply Recommended"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context) -> bool:
        return context.scene is not None and recommended_settings(context.scene) is not None

    def execute(self, context) -> set[str]:
        settings = recommended_settings(context.scene)
        settings.to_properties(context.scene.btf_render)
        rec = json.loads(context.scene.btf_accuracy.report)["recommendation"]
        texel_filter = rec["knobs"].get("texel_filter")
        if texel_filter is not None:  # a material knob: the estimate set every BTF material's
            for material in bpy.data.materials:
                if material.library is None and material.btf.enabled:
                    material.btf.texel_filter = texel_filter
        self.report({"INFO"}, f"Applied {rec['describe']}")
        return {"FINISHED"}


# ---------------------------------------------------------------------------------------------
# The panel's plot: an image preview (an icon of any size) filled with the plot raster.

_previews = None
_preview_key: dict[str, str] = {}


def plot_preview(scene):
    """The ImagePreview holding the plot of ``scene``'s stored report (redrawn when the report
    changes), or None without a report."""
    text = scene.btf_accuracy.report
    if not text or _previews is None:
        return None
    name = f"plot-{scene.as_pointer()}"
    preview = _previews.get(name) or _previews.new(name)
    if _preview_key.get(name) != text:
        data = json.loads(text)
        if not data["points"]:
            return None
        rgb = error_plot(data, "rmse", PLOT_SIZE)
        rgba = np.concatenate([rgb, np.full((*rgb.shape[:2], 1), 255, np.uint8)], axis=-1)
        preview.image_size = (rgba.shape[1], rgba.shape[0])
        # Previews store rows bottom first, as float RGBA in [0, 1].
        preview.image_pixels_float = (rgba[::-1].astype(np.float32) / 255.0).ravel()
        _preview_key[name] = text
    return preview


class BTF_PT_render_accuracy(Panel):
    bl_label = "Quality vs Time"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_parent_id = "BTF_PT_render_settings"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context) -> bool:
        return context.engine == ENGINE_ID

    def draw(self, context) -> None:
        scene = context.scene
        props = scene.btf_accuracy
        layout = self.layout
        layout.use_property_split = True
        col = layout.column()
        col.prop(props, "budget")
        col.prop(props, "target")
        col.prop(props, "thoroughness")
        if props.thoroughness == "FULL":
            col.prop(props, "preview_size")
            col.prop(props, "reference_samples")
        col.prop(props, "include_bake")
        job = running_job(scene)
        if job is not None:
            progress_row(layout, job, "btf.estimate_quality_cancel")
            return
        layout.operator("btf.estimate_quality", icon="TIME")
        if not props.report:
            return
        data = json.loads(props.report)
        preview = plot_preview(scene)
        if preview is not None:
            layout.template_icon(icon_value=preview.icon_id, scale=12.0)
        if data.get("bake"):  # Include Light Bake: its settings, scene's own first
            bake_box = layout.box()
            bake_box.label(text="Light bake for VR (baked objects' pixels)", icon="LIGHT")
            for row in data["bake"]:
                bake_box.label(text=row_words(row))
        rec = data.get("recommendation")
        box = layout.box()
        if data.get("interrupted"):
            done, total = data["rungs_done"], data["rungs_total"]
            box.label(text=f"Cancelled: {done} of {total} settings measured", icon="INFO")
        if rec is None:
            box.label(text="No recommendation yet")
            return
        box.label(text=f"Recommended: {rec['words']}")
        box.label(text=f"Error {rec['rmse']:.1%} of the image's brightness (RMS)")
        if not rec["met"]:
            box.label(text=rec.get("reason_words", rec["reason"]), icon="ERROR")
        box.operator("btf.apply_recommended", icon="CHECKMARK")


classes = (
    BTFAccuracySettings,
    BTF_OT_estimate_quality,
    BTF_OT_estimate_quality_cancel,
    BTF_OT_apply_recommended,
    BTF_PT_render_accuracy,
)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register() -> None:
    global _previews
    import bpy.utils.previews

    _register()
    _previews = bpy.utils.previews.new()


def unregister() -> None:
    global _previews
    import bpy.utils.previews

    stop_all(_jobs)
    if _previews is not None:
        bpy.utils.previews.remove(_previews)
        _previews = None
    _preview_key.clear()
    _unregister()

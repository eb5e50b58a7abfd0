"""Bake Light for VR: the light bake inside Blender (Render Properties › BTF Render › Light Bake,
and Render › Bake Light for VR, which F3 finds).

The scene is exported on the main thread (bpy), then baked and written on a worker thread
(blender/bake/run.py, the CLI's own functions: the same file and knobs give the same data) while
a modal timer shows progress; Esc or the panel's Cancel stops after the last finished pass of
samples and writes that bake. From a script (``bpy.ops.btf.bake_light()``, no window) it bakes
to the end before returning. The bake lies beside the saved .blend; the scene keeps its path
(relative, like BTF sources) and the report's JSON, whose one line per object the panel shows.

Re-baking: the bake already beside the .blend is read on the worker thread and only what is
stale or missing there is traced, the rest kept (blender/bake/run.py ``last_bake``, as the
CLI's ``bake``); Re-bake Everything (``rebake_all``) traces every object again.
"""

from __future__ import annotations

import json
import logging
import threading
from pathlib import Path

import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty, PointerProperty, StringProperty
from bpy.types import Operator, Panel, PropertyGroup

from ...cl.bake import BakeKnobs
from ...core.errors import BTFError
from ...render.light_bake import default_path
from .. import compat
from ..addon import ENGINE_ID
from ..background_job import PanelJobModal, progress_row, running_in, stop_all
from ..export.light_bake import last_status
from ..preferences import preferred_device
from .run import bake_exported, export_for_bake, knobs_for, last_bake, write_bake

log = logging.getLogger(__name__)
_DEFAULTS = BakeKnobs()


class BTFBakeSettings(PropertyGroup):
    spacing: FloatProperty(
        name="Spacing",
        description="Distance between bake points on the surfaces (finer: sharper contact "
        "shadows, more bake time and memory)",
        default=_DEFAULTS.spacing,
        min=0.001,
        soft_max=1.0,
        subtype="DISTANCE",
    )
    view_bins: IntProperty(
        name="View Directions",
        description="View directions per side of the baked grid (their square in total)",
        default=_DEFAULTS.view_bins,
        min=1,
        max=16,
    )
    samples: IntProperty(
        name="Samples",
        description="Light paths per bake point and view direction",
        default=_DEFAULTS.samples,
        min=16,
        soft_max=1024,
    )
    path: StringProperty(
        name="Bake File",
        description="The last light bake of this scene (relative to the .blend)",
        subtype="FILE_PATH",
        options=compat.path_property_options(),  # "//" paths without Blender 4.5's warning
    )
    report: StringProperty(name="Bake Report", description="The last bake's report (JSON)")


class Job:
    """One bake on a worker thread; the thread touches no bpy data. ``everything``: trace
    every object, not only what is stale or missing in the bake already at ``path``."""

    def __init__(self, exported, knobs: BakeKnobs, path: Path, everything: bool = False):
        self.exported, self.knobs, self.path = exported, knobs, path
        self.everything = everything
        self.note = ""  # why the last bake was not used, when it could not be
        self.cancel = threading.Event()
        self.done = threading.Event()
        self.fraction, self.text = 0.0, "opening the OpenCL device, loading the kernels"
        self.error: BaseException | None = None
        self.bake = None
        self.thread = threading.Thread(target=self._work, name="btf-bake", daemon=True)

    def _progress(self, fraction: float) -> bool:
        self.fraction, self.text = fraction, "baking"
        return not self.cancel.is_set()

    def _work(self) -> None:
        try:
            self.text = "reading the last bake"
            previous, self.note = last_bake(self.path, self.everything)
            self.text = "opening the OpenCL device, loading the kernels"
            bake = bake_exported(
                self.exported, self.knobs, preferred_device(), self._progress, previous
            )
            if bake.knobs["samples"] > 0 or not any(m.baked for m in bake.meshes):
                self.text = "writing"
                write_bake(bake, self.path)
                self.bake = bake
        except Exception as exc:  # shown by the operator on the main thread
            log.exception("light bake failed")
            self.error = exc
        finally:
            self.done.set()


_jobs: dict[int, Job] = {}


def running_job(scene) -> Job | None:
    return running_in(_jobs, scene)


def start_job(context, everything: bool = False) -> Job:
    """Check, export on this (main) thread, then start the worker (``everything``: Job's)."""
    if not bpy.data.filepath:
        raise BTFError("save the .blend first: the light bake is written beside it")
    scene = context.scene
    props = scene.btf_bake
    knobs = knobs_for(scene, props.spacing, props.view_bins, props.samples)
    path = default_path(bpy.path.abspath(bpy.data.filepath), scene.name)
    exported = export_for_bake(context.evaluated_depsgraph_get())
    job = Job(exported, knobs, path, everything)
    _jobs[scene.as_pointer()] = job
    job.thread.start()
    return job


def finish_job(operator, context, job: Job) -> set[str]:
    """On the main thread: keep the path and the report, say what happened."""
    _jobs.pop(context.scene.as_pointer(), None)
    if job.error is not None:
        operator.report({"ERROR"}, f"Light bake failed: {job.error}")
        return {"CANCELLED"}
    if job.bake is None:
        operator.report({"WARNING"}, "Light bake cancelled before its first pass: nothing written")
        return {"CANCELLED"}
    props = context.scene.btf_bake
    props.path = bpy.path.relpath(str(job.path))
    props.report = json.dumps(job.bake.report())
    if job.note:
        operator.report({"WARNING"}, f"Light bake: {job.note}")
    baked = [m for m in job.bake.meshes if m.baked]
    kept = sum(m.kept for m in baked)
    kept_text = f" ({kept} kept unchanged since the last bake)" if kept else ""
    stopped = " (cancelled early)" if job.cancel.is_set() else ""
    operator.report(
        {"INFO"},
        f"Light bake: {len(baked)} of {len(job.bake.meshes)} objects baked{kept_text}, "
        f"{job.bake.knobs['samples']} samples, {job.bake.seconds:.1f} s{stopped}",
    )
    return {"FINISHED"}


def report_lines(scene) -> list[str]:
    """The last bake's one line per object (empty before any)."""
    try:
        data = json.loads(scene.btf_bake.report) if scene.btf_bake.report else None
    except json.JSONDecodeError:
        return []
    if not data:
        return []
    from ...render.light_bake import MeshBake

    return [MeshBake(**m).line() for m in data["meshes"]]


class BTF_OT_bake_light(PanelJobModal, Operator):
    """Precompute shadows and light between objects for the VR preview with the final
    render's path tracer, for the objects that need it, and write the bake beside the .blend"""

    bl_idname = "btf.bake_light"
    bl_label = "Bake Light for VR"
    # Writes a file and the scene's bake path and report; no edit a user makes is touched.
    bl_options = {"REGISTER"}
    status_label = "Light Bake"

    rebake_all: BoolProperty(
        name="Re-bake Everything",
        description="Bake every object again; by default the objects whose last bake still "
        "holds (they, the objects beside them, the lights and the World unchanged) keep it",
        default=False,
    )

    @classmethod
    def poll(cls, context) -> bool:
        scene = context.scene
        return scene is not None and scene.render.engine == ENGINE_ID and not running_job(scene)

    def _begin(self, context) -> Job:
        return start_job(context, self.rebake_all)

    def _finish(self, context, job: Job) -> set[str]:
        return finish_job(self, context, job)


class BTF_OT_bake_light_cancel(Operator):
    """Stop the running light bake after its current pass and write what is finished"""

    bl_idname = "btf.bake_light_cancel"
    bl_label = "Cancel Light Bake"
    bl_options = {"INTERNAL"}

    def execute(self, context) -> set[str]:
        job = running_job(context.scene)
        if job is not None:
            job.cancel.set()
        return {"FINISHED"}


class BTF_PT_render_light_bake(Panel):
    bl_label = "Light Bake for VR"
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
        props = scene.btf_bake
        layout = self.layout
        layout.use_property_split = True
        col = layout.column()
        col.prop(props, "spacing")
        col.prop(props, "view_bins")
        col.prop(props, "samples")
        job = running_job(scene)
        if job is None:
            row = layout.row(align=True)
            row.operator(BTF_OT_bake_light.bl_idname, icon="RENDER_STILL")
            everything = row.operator(BTF_OT_bake_light.bl_idname, text="", icon="FILE_REFRESH")
            everything.rebake_all = True
        else:
            progress_row(layout, job, BTF_OT_bake_light_cancel.bl_idname)
        if props.path:
            layout.prop(props, "path")
        status = last_status(scene)  # what the viewport or the headset last drew
        if status:
            layout.label(text=status, icon="ERROR" if "stale" in status else "LIGHT")
        for line in report_lines(scene):
            layout.label(text=line)


def _render_menu(self, _context) -> None:
    self.layout.operator(BTF_OT_bake_light.bl_idname, icon="RENDER_STILL")


classes = (BTFBakeSettings, BTF_OT_bake_light, BTF_OT_bake_light_cancel, BTF_PT_render_light_bake)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register() -> None:
    _register()
    bpy.types.Scene.btf_bake = PointerProperty(type=BTFBakeSettings)
    bpy.types.TOPBAR_MT_render.append(_render_menu)  # Render › Bake Light for VR, found by F3


def unregister() -> None:
    stop_all(_jobs)
    bpy.types.TOPBAR_MT_render.remove(_render_menu)
    del bpy.types.Scene.btf_bake
    _unregister()

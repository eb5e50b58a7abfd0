"""The modal half of an operator whose work runs on a worker thread: a progress bar and status
text refreshed by a timer, Esc to cancel, the result handled on the main thread. Used by
Estimate Quality vs Time (accuracy_operator.py) and Compress BTF (compress_operator.py).

A job is anything with ``fraction`` (0–1), ``text``, and the ``threading.Event``s ``cancel``
and ``done``. The operator defines ``_start(context) -> job | None`` (None: it reported why),
``_end(context, job) -> {'FINISHED'} | {'CANCELLED'}``, ``status_label`` and ``execute`` (from
a script, or without a window as in background Blender: the whole job before returning).
``PanelJobModal`` writes those four for a job whose panel shows its progress and result (Estimate
Quality vs Time, Bake Light for VR): the operator gives only how to begin and how to finish;
``running_in``, ``stop_all`` and ``progress_row`` are what such a panel and its module share
(a job per scene, stopped at unregister, shown with a cancel button)."""

from __future__ import annotations

from ..core.errors import BTFError

TICK_SECONDS = 0.25  # how often progress is shown; also how late a finished job is noticed


def running_in(jobs: dict, scene):
    """The job of ``jobs`` (an operator's running jobs by the scene's session pointer) that
    ``scene`` is running, None where it runs none or its job has ended."""
    job = jobs.get(scene.as_pointer())
    return job if job is not None and not job.done.is_set() else None


def stop_all(jobs: dict) -> None:
    """Cancel and wait for every job of ``jobs`` (unregister: a worker must not outlive the
    add-on's classes)."""
    for job in list(jobs.values()):
        job.cancel.set()
        job.thread.join()
    jobs.clear()


def progress_row(layout, job, cancel_idname: str) -> None:
    """A panel's row for a running job: its progress bar (a label before Blender 4.0) and the
    cancel button."""
    row = layout.row()
    text = f"{job.fraction:.0%} {job.text}"
    if hasattr(row, "progress"):  # Blender 4.0+
        row.progress(factor=job.fraction, type="BAR", text=text)
    else:
        row.label(text=text)
    row.operator(cancel_idname, text="", icon="CANCEL")


def redraw_properties(context) -> None:
    """Tag every Properties editor for redraw: a job's panel shows its progress and result."""
    for window in getattr(context.window_manager, "windows", ()):
        for area in window.screen.areas:
            if area.type == "PROPERTIES":
                area.tag_redraw()


class BackgroundJobModal:
    """Mixin placed before ``bpy.types.Operator`` in the bases."""

    status_label = ""
    _timer = None
    _job = None

    def _tick(self, context) -> None:
        """Per timer tick, after the progress is shown (a panel's redraw)."""

    def invoke(self, context, _event) -> set[str]:
        if context.window is None:
            return self.execute(context)
        job = self._start(context)
        if job is None:
            return {"CANCELLED"}
        self._job = job
        wm = context.window_manager
        self._timer = wm.event_timer_add(TICK_SECONDS, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 100)
        return {"RUNNING_MODAL"}

    def modal(self, context, event) -> set[str]:
        job = self._job
        if event.type == "ESC":
            job.cancel.set()
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        wm = context.window_manager
        wm.progress_update(int(job.fraction * 100))
        context.workspace.status_text_set(f"{self.status_label}: {job.fraction:.0%} {job.text}")
        self._tick(context)
        if not job.done.is_set():
            return {"PASS_THROUGH"}
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)
        return self._end(context, job)


class PanelJobModal(BackgroundJobModal):
    """A job started from a Properties panel that shows its progress and result. The operator
    defines ``_begin(context) -> job`` (raising BTFError, with what to do, where it cannot
    start) and ``_finish(context, job) -> {'FINISHED'} | {'CANCELLED'}`` (on the main thread:
    the job's result into the scene and the operator's report)."""

    def _start(self, context):
        try:
            return self._begin(context)
        except BTFError as exc:
            self.report({"ERROR"}, str(exc))
            return None

    def execute(self, context) -> set[str]:
        """From a script or background Blender: the whole job before returning."""
        job = self._start(context)
        if job is None:
            return {"CANCELLED"}
        job.done.wait()
        job.thread.join()
        return self._finish(context, job)

    def _tick(self, context) -> None:
        redraw_properties(context)  # the panel's progress

    def _end(self, context, job) -> set[str]:
        result = self._finish(context, job)
        redraw_properties(context)  # and its result
        return result

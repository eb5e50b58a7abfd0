"""``accuracy``: what accuracy costs in time for one .blend — the report command.

The file is opened as ``render --blend`` opens it (its scene's own render settings are the
starting point), the scene is exported once at a reduced size, and every quality knob that
applies is swept by the final render's own OpenCL renderer (blender/accuracy/run.py), against a
reference rendered once at high quality. Ctrl-C stops after writing what is done.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from ..render.accuracy.ladder import describe_rung, run, verify_recommendation
from ..render.accuracy.report import to_json, write_json, write_report
from .blend_file import check_blend, import_bpy, open_blend

DESCRIPTION = """\
Estimate what accuracy costs in time for a .blend's camera view: every quality knob that
applies (final mode; Virtual Lights: N; Sampled: samples, bounces) is rendered at a reduced
size (--size: the longest side in pixels) through the F12 OpenCL renderer, and scored against
a reference rendered once with the World sampled at --reference-samples samples and
--reference-bounces bounces (its own time is in the report).

Errors: relative RMSE (linear radiance) and 1 - SSIM (structure of the displayed sRGB
luminance). Times are predicted for the scene's own resolution from the time per pixel·light /
pixel·sample measured here, plus the measured setup (export, device, upload).

Output (REPORT_DIR, default ./accuracy_report): report.json (rewritten after every rung, so an
interrupted run keeps what it did), report.md and report.html with error-vs-time plots (PNG),
the Pareto front, heat maps of where the error sits, and the recommended settings: the most
accurate within --budget seconds, the fastest reaching --target relative RMSE, or both
(default: --target 0.02).
"""


def add_parser(sub) -> None:
    import argparse

    p = sub.add_parser(
        "accuracy",
        help="error against time for a .blend's quality settings, with a recommendation",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--blend", type=Path, required=True, help="the .blend (its active scene)")
    p.add_argument("-o", "--output", type=Path, default=Path("accuracy_report"), metavar="DIR")
    p.add_argument(
        "--budget",
        type=_positive(float),
        metavar="SECONDS",
        help="time budget of one full-resolution render",
    )
    p.add_argument(
        "--target",
        type=_positive(float),
        metavar="RMSE",
        help="target relative RMSE (default 0.02 without --budget)",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="the quick estimate (Blender's default): the scene's own mode and its samples or "
        "lights only, a smaller preview and reference (--size 96, --reference-samples 256, "
        "--reference-bounces 4 unless given)",
    )
    p.add_argument(
        "--size",
        type=_positive(int),
        metavar="PIXELS",
        help="longest side of the reduced render (default 160; --quick: 96)",
    )
    p.add_argument("--reference-samples", type=_positive(int), metavar="N", help="default 1024")
    p.add_argument("--reference-bounces", type=_non_negative_int, metavar="N", help="default 8")
    p.add_argument("--device", type=int, metavar="N", help="OpenCL device index (`doctor`)")
    p.add_argument(
        "--bake",
        action="store_true",
        help="also the light bake's knobs (spacing, view directions, samples: one bake each, "
        "minutes on a CPU) against the same reference: error, bake time, GPU memory",
    )
    p.set_defaults(func=cmd_accuracy)


def _positive(kind):
    def parse(text: str):
        import argparse

        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
        return value

    return parse


def _non_negative_int(text: str) -> int:
    import argparse

    if not text.isdigit():
        raise argparse.ArgumentTypeError(f"must be an integer ≥ 0, got {text!r}")
    return int(text)


class ProgressBar:
    """One line on stderr, redrawn: [#####.....] 42 % reference (12.3 s)."""

    def __init__(self, stream=None, width: int = 30):
        self.stream, self.width, self.t0 = stream or sys.stderr, width, time.perf_counter()
        self.last = ""

    def __call__(self, fraction: float, text: str) -> None:
        if not self.stream.isatty():  # a log: one line per step, not a redrawn bar
            if text != self.last:
                self.stream.write(f"{fraction:4.0%} {text}\n")
                self.last = text
            return
        filled = round(fraction * self.width)
        line = (
            f"[{'#' * filled}{'.' * (self.width - filled)}] {fraction:4.0%} {text[:48]:<48} "
            f"({time.perf_counter() - self.t0:.1f} s)"
        )
        if line != self.last:
            self.stream.write("\r" + line)
            self.stream.flush()
            self.last = line

    def close(self) -> None:
        if self.stream.isatty():
            self.stream.write("\n")


class FullSizes:
    """The full estimate's preview and reference (the command's defaults)."""

    longest = 160
    reference_samples = 1024
    reference_bounces = 8


def cmd_accuracy(args) -> int:
    check_blend(args.blend)  # before Blender starts
    target = args.target if args.target is not None or args.budget is not None else 0.02
    bpy = import_bpy("the estimate")
    from ..blender.accuracy.run import QuickSizes, prepare, run_bake_sweep
    from ..blender.bake.run import knobs_for
    from .render_command import _engine_registered

    sizes = QuickSizes if args.quick else FullSizes

    def given(value, default):
        return default if value is None else value

    folder = args.output.resolve()
    with _engine_registered(bpy):
        open_blend(bpy, args.blend)
        estimate, rungs, renderer = prepare(
            bpy.context.evaluated_depsgraph_get(),
            given(args.size, sizes.longest),
            args.device,
            given(args.reference_samples, sizes.reference_samples),
            given(args.reference_bounces, sizes.reference_bounces),
            quick=args.quick,
        )
        props = bpy.context.scene.btf_bake  # the bake's own knobs, as Bake Light for VR
        bake_knobs = knobs_for(bpy.context.scene, props.spacing, props.view_bins, props.samples)
    pw, ph = estimate.preview_size
    fw, fh = estimate.full_size
    print(
        f"{len(rungs)} settings + reference at {pw}x{ph} (full {fw}x{fh}) on {estimate.device}; "
        f"report -> {folder}",
        file=sys.stderr,
    )
    bar = ProgressBar()
    try:
        run(
            estimate,
            rungs,
            renderer,
            on_progress=bar,
            on_point=lambda e: write_json(folder, to_json(e, args.budget, target)),
        )
        if not estimate.interrupted:
            bar(1.0, "verifying the recommendation with more seeds")
            verify_recommendation(estimate, renderer, args.budget, target)
        if args.bake and not estimate.interrupted:
            run_bake_sweep(estimate, renderer, bake_knobs, on_progress=bar)
    except KeyboardInterrupt:
        estimate.interrupted = True
    finally:
        bar.close()
        write_report(folder, estimate, args.budget, target)
    data = to_json(estimate, args.budget, target)
    rec = data["recommendation"]
    if estimate.interrupted:
        print(f"interrupted: {len(estimate.points)} of {len(rungs)} rungs kept", file=sys.stderr)
    if rec is None:
        print(f"no rung finished; report: {folder / 'report.md'}")
        return 130 if estimate.interrupted else 1
    chosen = estimate.points[rec["index"]]
    print(
        f"recommended: {describe_rung(chosen.rung)} ({rec['reason']}): relative RMSE "
        f"{chosen.rmse:.4f}{_bound(chosen.rmse_upper)}, 1-SSIM {chosen.ssim_loss:.4f}, predicted "
        f"{chosen.predicted_seconds:.2f} s at {fw}x{fh}; reference "
        f"{estimate.reference_seconds:.2f} s at {pw}x{ph}; report: {folder / 'report.md'}"
    )
    return 130 if estimate.interrupted else 0


def _bound(upper: float) -> str:
    return f" (90 % bound {upper:.4f})" if upper == upper else ""  # NaN: one image, no bound

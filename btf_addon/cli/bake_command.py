"""``bake``: precompute a .blend's light for VR (shadows, interreflection) per object, with the
final render's own paths (blender/bake/run.py; representation and costs: docs/accuracy.md
"The light bake"). The scene is analysed first and only the objects whose image a shadow or a
reflection changes are baked; the report says what was baked for each object and why."""

from __future__ import annotations

import sys
from pathlib import Path

from ..cl.bake import BakeKnobs
from ..core import interrupts
from ..core.fileio import check_output
from .accuracy_command import ProgressBar, _positive
from .blend_file import check_blend, import_bpy, open_blend

DESCRIPTION = """\
Bake a .blend's light for the VR preview: for each object that needs it (the scene analysis:
a lone convex object under the World needs nothing; an object on a ground gets its contact
shadow; objects that see each other get their interreflection), the light F12's path tracer
computes, stored per bake point (a surface grid --spacing apart, whatever the UVs) and per view
direction (--view-bins squared), as a ratio over the material's live decode so that texel
detail stays sharp.

Output (DIR, default the .blend's folder): <file>.<scene>.light_bake.npz, written whole, and
<file>.<scene>.light_bake.json, the report (per object: baked, kept or skipped, why, points,
time). Ctrl-C stops after the last finished pass of samples and writes that (noisier) bake.

Re-baking: where that .npz exists already, an object whose bake still holds (it, the objects
beside it, the lights and the World unchanged, the same knobs) keeps its values from it and
only the others are traced; the report says which were kept. --all bakes everything again.
"""


def add_parser(sub) -> None:
    import argparse

    defaults = BakeKnobs()
    p = sub.add_parser(
        "bake",
        help="precompute a .blend's shadows and interreflection for the VR preview",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--blend", type=Path, required=True, help="the .blend (its active scene)")
    p.add_argument("-o", "--output", type=Path, metavar="DIR", help="default: beside the .blend")
    p.add_argument(
        "--spacing",
        type=_positive(float),
        default=defaults.spacing,
        help=f"distance between bake points in scene units (default {defaults.spacing})",
    )
    p.add_argument(
        "--view-bins",
        type=_positive(int),
        default=defaults.view_bins,
        help=f"view directions per side of the concentric square (default {defaults.view_bins})",
    )
    p.add_argument(
        "--samples",
        type=_positive(int),
        default=defaults.samples,
        help=f"paths per bake point and view direction (default {defaults.samples})",
    )
    p.add_argument("--device", type=int, metavar="N", help="OpenCL device index (`doctor`)")
    p.add_argument(
        "--all",
        action="store_true",
        help="bake every object again (default: keep those unchanged since the last bake)",
    )
    p.set_defaults(func=cmd_bake)


def cmd_bake(args) -> int:
    check_blend(args.blend)  # before Blender starts
    bpy = import_bpy("the bake")
    from ..blender.bake.run import (
        bake_exported,
        export_for_bake,
        kept_summary,
        knobs_for,
        last_bake,
        write_bake,
    )
    from ..render.light_bake import default_path
    from .render_command import _engine_registered

    with _engine_registered(bpy):
        open_blend(bpy, args.blend)
        scene = bpy.context.scene
        path = default_path(args.blend.resolve(), scene.name)
        if args.output is not None:
            path = args.output.resolve() / path.name
        check_output(path)
        knobs = knobs_for(scene, args.spacing, args.view_bins, args.samples)
        bar = ProgressBar()

        def progress(fraction: float) -> bool:
            bar(fraction, "baking")
            return not interrupts.pending()  # Ctrl-C: stop after the last finished pass

        # Held back, so a Ctrl-C ends the bake between launches and what was finished is
        # written whole; the signal is delivered (exit 130) when the block ends.
        with interrupts.deferred():
            previous, why = last_bake(path, everything=args.all)
            if why:
                print(why, file=sys.stderr)
            try:
                exported = export_for_bake(bpy.context.evaluated_depsgraph_get())
                bake = bake_exported(exported, knobs, args.device, progress, previous)
            finally:
                bar.close()
            if bake.knobs["samples"] == 0 and any(m.baked for m in bake.meshes):
                print("stopped before the first pass finished: nothing written", file=sys.stderr)
                return 130
            report = write_bake(bake, path)
            for mesh in bake.meshes:
                print(mesh.line())
            if summary := kept_summary(bake):
                print(summary)
            print(
                f"light bake: {path} ({bake.nbytes / 2**20:.1f} MiB, {bake.seconds:.1f} s, "
                f"{bake.knobs['samples']} samples); report: {report}",
                file=sys.stderr,
            )
    return 0

"""Compress BTF (File › Export is not the place: it writes a material, not the scene):
``bpy.ops.btf.compress(filepath=SRC, output=OUT.btfm, ...)`` encodes any BTF the add-on
reads to our own MLVQ (core/encoders/mlvq.py) or, with ``codec="SVD"``, to the ``svd`` codec
at ``rank`` components per channel in RGB or YUV (core/encoders/svd.py).

The encode runs on a worker thread (bpy-free: it reads only the loaded BTF and writes only the
``Job``); a modal timer shows its progress in the status bar; Esc cancels between k-means
steps (SVD: between texel or direction blocks and between channels). The output is written
atomically after a finished encode, so a cancel leaves no file. Run from a script (no window),
it encodes before returning.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path

from bpy.props import EnumProperty, IntProperty, StringProperty
from bpy.types import Operator

from ...cl.encoder_assign import opencl_assign_or_none
from ...core.encoders import metrics
from ...core.encoders.mlvq import MLVQSettings, encode_mlvq
from ...core.encoders.svd import SVDSettings, encode_svd
from ...core.encoders.svd import sizes as svd_sizes
from ...core.errors import BTFError
from ...core.formats.container import SUFFIX, write_container
from ...core.formats.load import load_btf
from ..background_job import BackgroundJobModal

log = logging.getLogger(__name__)


class CancelledError(Exception):
    """Raised inside the encoder's progress callback when the user cancelled."""


class Job:
    """One encode on a worker thread; the modal timer reads ``fraction``/``text``."""

    def __init__(self, src: str, out: Path, settings: MLVQSettings | SVDSettings):
        self.src, self.out, self.settings = src, out, settings
        self.cancel = threading.Event()
        self.done = threading.Event()
        self.fraction, self.text = 0.0, "loading"
        self.error: BaseException | None = None
        self.summary = ""
        self.thread = threading.Thread(target=self._work, name="btf-compress", daemon=True)

    def _progress(self, fraction: float, text: str) -> None:
        if self.cancel.is_set():
            raise CancelledError
        self.fraction, self.text = fraction, text

    def _work(self) -> None:
        try:
            btf = load_btf(self.src)
            if isinstance(self.settings, SVDSettings):
                encoded, stats = encode_svd(btf, self.settings, self._progress)
                write_container(self.out, encoded)
                ratio = svd_sizes(encoded).stored_ratio
                ranks = "/".join(str(k) for k in stats.ranks)
                self.summary = (
                    f"{self.out.name}: svd rank {ranks}, ratio {ratio:.0f}:1 against 8-bit "
                    f"data, {stats.seconds:.1f} s"
                )
                return
            assign = opencl_assign_or_none()  # a GPU's OpenCL step, else numpy
            encoded, stats = encode_mlvq(btf, self.settings, self._progress, assign=assign)
            write_container(self.out, encoded)
            size = metrics.sizes(encoded, self.settings.scale_bits)
            self.summary = (
                f"{self.out.name}: ratio {size.packed_ratio:.0f}:1 packed "
                f"({size.stored_ratio:.0f}:1 as stored), {stats.seconds:.1f} s"
            )
        except CancelledError:
            pass
        except BTFError as exc:  # the user's input: the message says it all
            self.error = exc
        except Exception as exc:  # shown by the operator on the main thread
            log.exception("compress failed")
            self.error = exc
        finally:
            self.done.set()


class BTF_OT_compress(BackgroundJobModal, Operator):
    """Compress a BTF (BTFbase folder or .btfm, any codec) to MLVQ or SVD in a .btfm file"""

    bl_idname = "btf.compress"
    bl_label = "Compress BTF"
    bl_options = {"REGISTER"}

    filepath: StringProperty(name="Input", subtype="FILE_PATH")
    output: StringProperty(name="Output", subtype="FILE_PATH")
    codec: EnumProperty(
        name="Codec",
        items=(
            ("MLVQ", "MLVQ", "Multi-level vector quantisation (BTFbase's codec)", 0),
            ("SVD", "SVD", "Truncated SVD per colour channel (UBO2014's DFMF)", 1),
        ),
        default="MLVQ",
    )
    rank: IntProperty(
        name="Rank", description="SVD: components kept per channel", default=16, min=1, max=4096
    )
    colour_space: EnumProperty(
        name="Colour Space",
        items=(
            ("YUV", "YUV", "SVD of decorrelated luminance and chrominance", 0),
            ("RGB", "RGB", "SVD of R, G and B", 1),
        ),
        default="YUV",
    )
    k1: IntProperty(name="P1 Slices", default=MLVQSettings.k1, min=1)
    k2: IntProperty(name="2D Functions", default=MLVQSettings.k2, min=1)
    k3: IntProperty(name="P3 Rows", default=MLVQSettings.k3, min=1)
    k4: IntProperty(name="P4 Rows", default=MLVQSettings.k4, min=1)
    scale_bits: IntProperty(name="Scale Bits", default=MLVQSettings.scale_bits, min=0, max=16)
    seed: IntProperty(name="Seed", default=0, min=0)
    status_label = "Compress BTF"

    def _start(self, _context) -> Job | None:
        try:
            if not self.filepath:
                raise BTFError("choose the BTF to compress")
            kind = self.codec.lower()
            out = Path(self.output or Path(self.filepath).with_suffix(f".{kind}{SUFFIX}"))
            out = out if out.suffix else out.with_suffix(SUFFIX)
            settings = (
                SVDSettings(ranks=self.rank, colour_space=self.colour_space.lower())
                if self.codec == "SVD"
                else MLVQSettings(
                    k1=self.k1,
                    k2=self.k2,
                    k3=self.k3,
                    k4=self.k4,
                    scale_bits=self.scale_bits,
                    seed=self.seed,
                )
            )
        except BTFError as exc:
            self.report({"ERROR"}, str(exc))
            return None
        job = Job(self.filepath, out, settings)
        job.thread.start()
        return job

    def _end(self, _context, job: Job) -> set[str]:
        if job.error is not None:
            self.report({"ERROR"}, f"Compress failed: {job.error}")
            return {"CANCELLED"}
        if job.cancel.is_set() and not job.summary:
            self.report({"WARNING"}, "Compress cancelled: no file written")
            return {"CANCELLED"}
        self.report({"INFO"}, job.summary)
        return {"FINISHED"}

    def execute(self, context) -> set[str]:
        job = self._start(context)
        if job is None:
            return {"CANCELLED"}
        job.thread.join()
        return self._end(context, job)


CLASSES = (BTF_OT_compress,)


def register() -> None:
    import bpy

    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    import bpy

    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)

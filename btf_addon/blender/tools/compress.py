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
import math
import threading
from pathlib import Path

from bpy.props import EnumProperty, IntProperty, StringProperty
from bpy.types import Operator

from ...cl.encoder_assign import opencl_assign_or_none
from ...core.encoders import metrics
from ...core.encoders.mlvq import MLVQSettings, encode_mlvq
from ...core.encoders.svd import SVDSettings, encode_svd
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
                ranks = "/".join(str(k) for k in stats.ranks)
                what = f"svd rank {ranks}"
            else:
                assign = opencl_assign_or_none()  # a GPU's OpenCL step, else numpy
                encoded, stats = encode_mlvq(btf, self.settings, self._progress, assign=assign)
                what = "MLVQ"
            self._progress(1.0, "measuring PSNR and SSIM")
            quality = measure(btf, encoded)
            write_container(self.out, encoded)
            self.summary = summary(self.out, btf, what, quality, stats.seconds)
        except CancelledError:
            pass
        except BTFError as exc:  # the user's input: the message says it all
            self.error = exc
        except Exception as exc:  # shown by the operator on the main thread
            log.exception("compress failed")
            self.error = exc
        finally:
            self.done.set()


#: Texels at which PSNR is measured, as the command line's default (``--psnr-texels``).
PSNR_TEXELS = 256


def measure(btf, encoded) -> tuple[float, float]:
    """(PSNR in dB, SSIM) of the encoding against its input, as ``compress`` on the command
    line measures them (core/encoders/metrics.py)."""
    texels = metrics.texel_subset(btf.meta.width, btf.meta.height, PSNR_TEXELS)
    return metrics.psnr(btf, encoded, texels), metrics.ssim(btf, encoded)


def summary(out: Path, btf, what: str, quality: tuple[float, float], seconds: float) -> str:
    """One line: the quality, then what the ratio means — the file on disk against the
    measured data at 8 bits per channel (81 × 81 directions per texel, as BTFbase counts)."""
    psnr, ssim = quality
    raw = 81 * 81 * btf.meta.width * btf.meta.height * 3
    size = out.stat().st_size
    shown = "identical" if math.isinf(psnr) else f"{psnr:.1f} dB"
    return (
        f"{out.name}: {what}, PSNR {shown}, SSIM {ssim:.3f}; the file is {_bytes(size)}, "
        f"{raw / size:.0f}× smaller than the measured data at 8 bits ({_bytes(raw)}); "
        f"{seconds:.1f} s"
    )


def _bytes(n: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("KB", 1e3)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n} bytes"


#: The MLVQ codebook sizes of each preset (P1 slices, 2D functions, P3 rows, P4 rows): the
#: default (Balanced) lands near the original tool's sizes on alu; the others halve or double
#: every codebook (measured: docs/formats.md, "Compress presets").
PRESETS = {
    "SMALLEST": (700, 850, 270, 17),
    "BALANCED": (MLVQSettings.k1, MLVQSettings.k2, MLVQSettings.k3, MLVQSettings.k4),
    "BEST": (2800, 3400, 1080, 68),
}


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
    preset: EnumProperty(
        name="Quality",
        items=(
            ("SMALLEST", "Smallest", "Half the codebooks: the smallest file, visibly coarser", 0),
            ("BALANCED", "Balanced", "Codebooks near the original BTFbase tool's", 1),
            ("BEST", "Best Quality", "Twice the codebooks: a larger file, slower to encode", 2),
            ("CUSTOM", "Custom", "The codebook sizes under Advanced", 3),
        ),
        default="BALANCED",
    )
    k1: IntProperty(
        name="Slice Codebook",
        description="Entries of the first level: whole light slices of a view (P1)",
        default=MLVQSettings.k1,
        min=1,
    )
    k2: IntProperty(
        name="2D Function Codebook",
        description="Entries of the second level: 2D functions of the light direction",
        default=MLVQSettings.k2,
        min=1,
    )
    k3: IntProperty(
        name="Light Row Codebook",
        description="Entries of the third level: rows of the light grid (P3)",
        default=MLVQSettings.k3,
        min=1,
    )
    k4: IntProperty(
        name="View Row Codebook",
        description="Entries of the fourth level: rows of the view grid, per texel (P4)",
        default=MLVQSettings.k4,
        min=1,
    )
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
                    *self.codebooks(),
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

    def codebooks(self) -> tuple[int, int, int, int]:
        """(k1, k2, k3, k4) of the chosen preset, or the Advanced fields for Custom (also
        when a script or the redo panel set a codebook size and no preset)."""
        props = self.properties
        sizes_set = any(props.is_property_set(k) for k in ("k1", "k2", "k3", "k4"))
        if self.preset == "CUSTOM" or (sizes_set and not props.is_property_set("preset")):
            return self.k1, self.k2, self.k3, self.k4
        return PRESETS[self.preset]

    def draw(self, context) -> None:
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "filepath")
        layout.prop(self, "output")
        layout.prop(self, "codec")
        if self.codec == "SVD":
            layout.prop(self, "rank")
            layout.prop(self, "colour_space")
            return
        layout.prop(self, "preset")
        header, body = layout.panel("btf_compress_advanced", default_closed=True)
        header.label(text="Advanced")
        if body is not None:
            body.active = self.preset == "CUSTOM"
            for name in ("k1", "k2", "k3", "k4"):
                body.prop(self, name)
            body.prop(self, "scale_bits")
            body.prop(self, "seed")

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

"""The Compress BTF operator (blender/tools/compress.py) in bpy: writes the encoding,
reports a user error in one line, and a cancelled job writes nothing; its SVD choice (codec,
rank, colour space) reaches the encoder. Small synthetic input
(4×4 texels, small codebooks): ~3 s in all."""

from __future__ import annotations

import pytest

bpy = pytest.importorskip("bpy")

from btf_addon.blender.tools import compress as op  # noqa: E402
from btf_addon.core.encoders.mlvq import MLVQSettings  # noqa: E402
from btf_addon.core.encoders.svd import SVDSettings  # noqa: E402
from btf_addon.core.formats.container import write_container  # noqa: E402
from btf_addon.core.formats.load import load_btf  # noqa: E402


@pytest.fixture(scope="module")
def registered():
    """This checkout's operator, registered for the module; the installed extension's (the
    Blender tests enable it in the same process, under the same idname) is put back after,
    so its own unregister at exit finds it."""
    installed = getattr(bpy.types, op.BTF_OT_compress.__name__, None)
    op.register()
    yield
    op.unregister()
    if installed is not None:
        bpy.utils.register_class(installed)


@pytest.fixture
def source(tmp_path):
    from core.test_encoder_mlvq import synthetic

    return write_container(tmp_path / "src.btfm", synthetic())


def test_operator_writes_an_mlvq_material(registered, source, tmp_path):
    out = tmp_path / "out.btfm"
    result = bpy.ops.btf.compress(filepath=str(source), output=str(out), k1=24, k2=24, k3=8, k4=4)
    assert result == {"FINISHED"}
    assert load_btf(out).meta.codec == "mlvq"


def test_operator_reports_a_missing_input(registered, tmp_path):
    with pytest.raises(RuntimeError, match="no such file"):
        bpy.ops.btf.compress(filepath=str(tmp_path / "missing.btfm"))
    assert list(tmp_path.iterdir()) == []


def test_cancelled_job_writes_nothing(source, tmp_path):
    out = tmp_path / "cancelled.btfm"
    job = op.Job(str(source), out, MLVQSettings(k1=24, k2=24, k3=8, k4=4))
    job.cancel.set()  # Esc before the first progress step: the encoder stops there
    job.thread.start()
    job.thread.join(timeout=60)
    assert job.done.is_set() and job.error is None and job.summary == ""
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["src.btfm"]


@pytest.mark.parametrize("colour, model", [("RGB", 0), ("YUV", 1)])
def test_operator_writes_an_svd_material(registered, source, tmp_path, colour, model):
    out = tmp_path / "out.btfm"
    result = bpy.ops.btf.compress(
        filepath=str(source), output=str(out), codec="SVD", rank=3, colour_space=colour
    )
    assert result == {"FINISHED"}
    enc = load_btf(out)
    assert enc.meta.codec == "svd" and enc.ranks == (3, 3, 3) and enc.p.colour_model == model


def test_default_output_name_says_the_codec(registered, source):
    assert bpy.ops.btf.compress(filepath=str(source), codec="SVD", rank=1) == {"FINISHED"}
    assert load_btf(source.with_suffix(".svd.btfm")).meta.codec == "svd"


def test_cancelled_svd_job_writes_nothing(source, tmp_path):
    out = tmp_path / "cancelled.btfm"
    job = op.Job(str(source), out, SVDSettings(ranks=2))
    job.cancel.set()  # Esc before the first progress step: the encoder stops there
    job.thread.start()
    job.thread.join(timeout=60)
    assert job.done.is_set() and job.error is None and job.summary == ""
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["src.btfm"]

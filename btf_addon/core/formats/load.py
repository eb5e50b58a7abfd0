"""The one loader every tool uses (a path → a BTF): the file formats of this room, and the
``.btfm`` container through the codec registry (core/codecs/packed.py ``register_codec``: each
codec registers its name, class, device id and pack function at the end of its own module;
``packed.codecs()`` imports them all)."""

from __future__ import annotations

from pathlib import Path

from ..codecs import packed
from ..codecs.mlvq import MLVQBTF
from ..errors import BTFFormatError, UnsupportedBTFError
from ..model import BTF
from . import btfbase_binary, image_sets, ubo2014


def codec_class(name: str) -> type:
    """The class of the codec ``name`` (a container's ``codec`` field)."""
    codec = packed.codecs().get(name)
    if codec is None or codec.cls is None:
        raise UnsupportedBTFError(f"unknown BTF codec {name!r}")
    return codec.cls


def load_btf(path: str | Path) -> BTF:
    """A BTFbase material folder (text tables or ``binary.btf``), a ``.btfm`` container, a
    UBO2014 DFMF ``.btf``, a BTFbase ``binary.btf``, or a UBO2003/ATRIUM image set (zip or
    folder: at the largest power-of-two reduction that fits in memory, see
    ``image_sets.load_image_set``)."""
    from .container import read_container

    path = Path(path)
    if path.is_dir() and image_sets.is_image_set(path) and not _is_btfbase(path):
        return image_sets.load_image_set(path, texels="auto")
    if path.is_dir():
        return load_btfbase_directory(path)
    if not path.exists():
        raise BTFFormatError(f"{path}: no such file or directory")
    if btfbase_binary.is_binary_btf(path):
        return btfbase_binary.load_binary(path)
    if ubo2014.is_ubo2014(path):
        return ubo2014.load_ubo2014(path)
    if path.suffix.lower() == ".zip":
        return image_sets.load_image_set(path, texels="auto")
    return read_container(path)


def _is_btfbase(directory: Path) -> bool:
    return (directory / "all_materialInfo.txt").is_file() or (directory / "binary.btf").is_file()


def load_btfbase_directory(directory: Path) -> MLVQBTF:
    """A BTFbase folder: the text tables when all are there and read, else ``binary.btf``.

    The text tables are exact; ``binary.btf`` is their 8-bit form (docs/formats.md), so it is
    the fallback. ``meta.extra['btfbase_form']`` says which was used (``info`` prints it).
    """
    from ..codecs import btfbase_files

    binary = directory / "binary.btf"
    if btfbase_files.text_tables_complete(directory):
        try:
            btf = MLVQBTF.from_directory(directory)
        except BTFFormatError as exc:
            if not binary.is_file():
                raise
            btf = btfbase_binary.load_binary(binary)
            btf.meta.extra["text_tables_error"] = str(exc)
            return btf
        btf.meta.extra["btfbase_form"] = "text"
        return btf
    if binary.is_file():
        return btfbase_binary.load_binary(binary)
    return MLVQBTF.from_directory(directory)  # raises the message naming what is missing


def bytes_on_disk(path: str | Path, btf: BTF) -> int:
    from ..codecs import btfbase_files

    path = Path(path)
    if path.is_dir() and btf.meta.extra.get("file_format", "").startswith("ubo-image-set"):
        return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
    if path.is_dir() and btf.meta.extra.get("btfbase_form") == "binary":
        return (path / "binary.btf").stat().st_size
    if path.is_dir():
        return sum(
            f.stat().st_size for f in btfbase_files.files_of(path, btf.meta.name) if f.exists()
        )
    return path.stat().st_size

"""Codec registry and the one loader every tool uses: a path → a BTF."""

from __future__ import annotations

from pathlib import Path

from .analytic import GGXBTF, LambertianBTF, PrincipledBTF
from .dense import DenseBTF
from .errors import BTFFormatError, UnsupportedBTFError
from .microgeometry import MicrogeometryBTF
from .mlvq import MLVQBTF
from .model import BTF

CODECS: dict[str, type] = {
    "mlvq": MLVQBTF,
    "dense": DenseBTF,
    "lambertian": LambertianBTF,
    "ggx": GGXBTF,
    "principled": PrincipledBTF,
    "microgeometry": MicrogeometryBTF,
}


def codec_class(name: str) -> type:
    try:
        return CODECS[name]
    except KeyError:
        raise UnsupportedBTFError(f"unknown BTF codec {name!r}") from None


def load_btf(path: str | Path) -> BTF:
    """A BTFbase material directory or a ``.btfm`` container file."""
    from .container import read_container

    path = Path(path)
    if path.is_dir():
        return MLVQBTF.from_directory(path)
    if not path.exists():
        raise BTFFormatError(f"{path}: no such file or directory")
    return read_container(path)


def bytes_on_disk(path: str | Path, btf: BTF) -> int:
    from . import btfbase_files

    path = Path(path)
    if path.is_dir():
        return sum(
            f.stat().st_size for f in btfbase_files.files_of(path, btf.meta.name) if f.exists()
        )
    return path.stat().st_size

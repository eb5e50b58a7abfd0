"""The one loader every tool uses (a path → a BTF): the file formats of this room, and the
``.btfm`` container through the codec registry (core/codecs/packed.py ``register_codec``: each
codec registers its name, class, device id and pack function at the end of its own module;
``packed.codecs()`` imports them all)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..codecs import packed
from ..codecs.mlvq import INDEX_LINKS, MLVQBTF, TABLE_NAMES, MLVQParams, index_range
from ..errors import BTFFormatError, UnsupportedBTFError
from ..model import BTF
from . import btfbase_binary, image_sets, ubo2014


def codec_class(name: str) -> type:
    """The class of the codec ``name`` (a container's ``codec`` field)."""
    codec = packed.codecs().get(name)
    if codec is None or codec.cls is None:
        raise UnsupportedBTFError(f"unknown BTF codec {name!r}")
    return codec.cls


def load_btf(path: str | Path, prefer_binary: bool = False) -> BTF:
    """A BTFbase material folder (text tables and/or ``binary.btf``), a ``.btfm`` container, a
    UBO2014 DFMF ``.btf``, a BTFbase ``binary.btf``, or a UBO2003/ATRIUM image set (zip or
    folder: at the largest power-of-two reduction that fits in memory, see
    ``image_sets.load_image_set``).

    ``prefer_binary``: a BTFbase folder is read from its ``binary.btf`` alone (the text tables
    are not looked at); other paths ignore it. What the user should be told about the load
    (damaged text tables, approximate values) is ``load_warnings(btf)``."""
    from .container import read_container

    path = Path(path)
    if path.is_dir() and image_sets.is_image_set(path) and not _is_btfbase(path):
        return image_sets.load_image_set(path, texels="auto")
    if path.is_dir():
        return load_btfbase_directory(path, prefer_binary=prefer_binary)
    if not path.exists():
        raise BTFFormatError(f"{path}: no such file or directory")
    if btfbase_binary.is_binary_btf(path):
        return btfbase_binary.load_binary(path)
    if ubo2014.is_ubo2014(path):
        return ubo2014.load_ubo2014(path)
    if path.suffix.lower() == ".zip":
        return image_sets.load_image_set(path, texels="auto")
    return read_container(path)


def load_warnings(btf: BTF) -> list[str]:
    """What the user should see about how ``btf`` was loaded, one sentence each, each naming
    its file: a damaged BTFbase text table (and that ``binary.btf`` stood in for it), float
    values ``binary.btf`` could not restore exactly. Empty for a clean load. (The same list is
    ``btf.meta.extra['warnings']``; ``info`` prints it.)"""
    return list(btf.meta.extra.get("warnings", ()))


def _is_btfbase(directory: Path) -> bool:
    return (directory / "all_materialInfo.txt").is_file() or (directory / "binary.btf").is_file()


def load_btfbase_directory(directory: Path, prefer_binary: bool = False) -> MLVQBTF:
    """A BTFbase folder, table by table: each table from its text file when the file is there
    and valid, the others from ``binary.btf`` (docs/formats.md).

    The text tables are exact; ``binary.btf`` is their 8-bit form with the wrapped maxima
    restored where possible (core/formats/btfbase_recover.py). A text table that is present
    but damaged (unreadable, wrong shape, an index out of range) is replaced from
    ``binary.btf`` and reported in ``load_warnings`` and ``meta.extra['text_tables_error']``;
    without ``binary.btf`` it is an error. ``meta.extra``: ``btfbase_form`` ("text",
    "binary" or "text+binary"), ``btfbase_tables`` (table → "text" / "binary"),
    ``btfbase_recovery`` (per float table taken from ``binary.btf``: what was restored).
    ``prefer_binary`` reads ``binary.btf`` alone.
    """
    from ..codecs import btfbase_files

    binary = directory / "binary.btf"
    if prefer_binary:
        if not binary.is_file():
            raise BTFFormatError(
                f"{directory}: the binary form was asked for, but there is no binary.btf"
            )
        btf = btfbase_binary.load_binary(binary)
        return btf
    has_binary = binary.is_file()
    try:
        info = btfbase_files.read_material_info(directory)
    except (BTFFormatError, UnsupportedBTFError) as exc:
        if not has_binary:
            raise
        btf = btfbase_binary.load_binary(binary)
        if (directory / "all_materialInfo.txt").is_file():  # there, but unusable: say so
            _warn_damaged(btf, [f"{exc} — read binary.btf instead"])
        return btf

    text: dict[str, np.ndarray] = {}
    damaged: dict[str, str] = {}
    missing: dict[str, str] = {}
    for name, (file, integer, cols) in btfbase_files.table_files(info).items():
        path = directory / file
        if not path.is_file():
            missing[name] = f"{path}: file is missing"
            continue
        try:
            text[name] = btfbase_files.read_table(path, integer, cols)
        except BTFFormatError as exc:
            damaged[name] = str(exc)
    links = {} if missing or damaged else _link_problems(directory, info, text)
    if (missing or damaged or links) and not has_binary:
        raise BTFFormatError(next(iter({**damaged, **links, **missing}.values())))
    if not missing and not damaged and not links:
        btf = MLVQBTF(_params_of(info), text, source=str(directory))
        btf.meta.extra["btfbase_form"] = "text"
        btf.meta.extra["btfbase_tables"] = dict.fromkeys(TABLE_NAMES, "text")
        return btf

    head, stored, recovery = btfbase_binary.binary_tables(binary)
    params = _params_of(info)
    if _grid(params) != _grid(btfbase_binary.params_of(head)):  # another material: no mixing
        btf = btfbase_binary.load_binary(binary)
        _warn_damaged(
            btf,
            [
                f"{directory / 'all_materialInfo.txt'}: describes another parameterisation or "
                f"material than binary.btf; the text tables are incomplete, read binary.btf "
                f"instead"
            ],
        )
        return btf
    for name, table in list(text.items()):  # a text table the binary's counts contradict
        if table.shape != stored[name].shape:
            damaged[name] = (
                f"{directory / btfbase_files.table_files(info)[name][0]}: holds "
                f"{table.shape[0]}×{table.shape[1]} values, binary.btf {stored[name].shape[0]}"
                f"×{stored[name].shape[1]}"
            )
            del text[name]
    tables = {name: text.get(name, stored[name]) for name in TABLE_NAMES}
    for name, problem in _link_problems(directory, info, tables, only=set(text)).items():
        damaged[name] = problem
        tables[name] = stored[name]
        text.pop(name, None)
    btf = MLVQBTF(params, tables, source=str(directory))
    extra = btf.meta.extra
    extra["btfbase_form"] = "text+binary" if text else "binary"
    extra["btfbase_tables"] = {n: "text" if n in text else "binary" for n in TABLE_NAMES}
    files = btfbase_files.table_files(info)
    extra["btfbase_files"] = [
        "all_materialInfo.txt",
        *(files[n][0] for n in TABLE_NAMES if n in text),
        "binary.btf",
    ]
    used = {n: r for n, r in recovery.items() if n not in text}
    extra["btfbase_recovery"] = {n: r.to_json() for n, r in used.items()}
    _warn_damaged(
        btf, [f"{damaged[n]} — read from binary.btf instead" for n in TABLE_NAMES if n in damaged]
    )
    warnings = btfbase_binary.recovery_warnings(binary, used)
    if warnings:
        extra["warnings"] = extra.get("warnings", []) + warnings
    return btf


def _grid(p: MLVQParams) -> tuple:
    """What tables of two sources must share to be mixed: the angular parameterisation."""
    return (p.n_beta, p.n_alpha, p.n_theta, p.n_phi, p.use_cos_beta)


def _warn_damaged(btf: BTF, problems: list[str]) -> None:
    if problems:
        btf.meta.extra["text_tables_error"] = "; ".join(problems)
        btf.meta.extra["warnings"] = btf.meta.extra.get("warnings", []) + problems


def _params_of(info) -> MLVQParams:
    return MLVQParams(
        n_beta=info.n_beta,
        n_alpha=info.n_alpha,
        n_theta=info.n_theta,
        n_phi=info.n_phi,
        use_cos_beta=info.use_cos_beta,
        rows_offset=info.rows_offset,
        cols_offset=info.cols_offset,
        hdr_value=info.hdr_value if info.hdr else 1.0,
        n_views=info.n_views,
        n_lights=info.n_lights,
        name=info.name,
    )


def _link_problems(
    directory: Path, info, tables: dict[str, np.ndarray], only: set[str] | None = None
) -> dict[str, str]:
    """Index tables (among ``only``) whose entries fall outside their target table, each with
    the message naming its file."""
    from ..codecs import btfbase_files

    files = btfbase_files.table_files(info)
    problems: dict[str, str] = {}
    for index, cols, target, what, one_based in INDEX_LINKS:
        if (only is not None and index not in only) or index in problems:
            continue
        low, high = index_range(tables, target, one_based)
        try:
            btfbase_files.check_index_range(
                tables[index][:, cols], low, high, directory / files[index][0], what
            )
        except BTFFormatError as exc:
            problems[index] = str(exc)
    return problems


def bytes_on_disk(path: str | Path, btf: BTF) -> int:
    from ..codecs import btfbase_files

    path = Path(path)
    if path.is_dir() and btf.meta.extra.get("file_format", "").startswith("ubo-image-set"):
        return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
    if path.is_dir() and btf.meta.extra.get("btfbase_form") == "binary":
        return (path / "binary.btf").stat().st_size
    if path.is_dir() and "btfbase_files" in btf.meta.extra:  # the files a mixed load read
        return sum((path / f).stat().st_size for f in btf.meta.extra["btfbase_files"])
    if path.is_dir():
        return sum(
            f.stat().st_size for f in btfbase_files.files_of(path, btf.meta.name) if f.exists()
        )
    return path.stat().st_size

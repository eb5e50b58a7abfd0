"""Importance tables kept on disk between sessions, as compiled kernels are: a measured BTF's
table (btf_importance.py) takes about half a second of numpy per material, paid again by
every new Blender process's first Sampled F12 (a render farm's every frame; the demo's fixed
cost was 40 % this build). The table is a function of the material's content and of the
build's parameters and code, so it is stored under a digest of exactly those.

Key: BLAKE2b of the material's packed tables (core/codecs/packed.py: the codec, its header
and every table the kernels read, i.e. what the table is built from), the build parameters,
and the source text of btf_importance.py and of the codec's module (a changed build or codec
makes new keys; old files are simply no longer read). Files: ``<key>.npy``, the float32
density (views², grid, grid), 4 · 49 · 576 B = 113 KiB with the defaults, one per material
and parameter set (no eviction: a thousand materials take 110 MiB; remove the folder at will).

Where: ``set_cache_dir`` (Blender: the extension's user directory, removed with it), else
``BTF_TABLE_CACHE``, else ``$XDG_CACHE_HOME/btf_materials/importance``. ``BTF_TABLE_CACHE=off``
turns it off. A file that fails to read or is not a valid density (shape, finite, ≥ the
defensive floor) is rebuilt and replaced; a folder that cannot be written is logged once and
the table built each time, as without a cache. Writes are atomic (core/fileio.py): a killed
process never leaves a half-written table under a key.
"""

from __future__ import annotations

import hashlib
import inspect
import logging
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..fileio import atomic_write, user_cache_root

log = logging.getLogger(__name__)

OFF = "off"
_cache_dir_setting: Path | None = None
_warned: set[str] = set()
stats = {"disk_hits": 0, "stored": 0, "rejected": 0}


def set_cache_dir(path: str | Path | None) -> None:
    """Keep tables in ``path`` (None: back to the default, module docstring)."""
    global _cache_dir_setting
    _cache_dir_setting = Path(path) if path is not None else None


def cache_dir() -> Path | None:
    """The folder in use, None when the cache is off."""
    if _cache_dir_setting is not None:
        return _cache_dir_setting
    env = os.environ.get("BTF_TABLE_CACHE")
    if env:
        return None if env.strip().lower() == OFF else Path(env)
    return user_cache_root() / "btf_materials" / "importance"


def _source_text(obj) -> bytes:
    try:
        return Path(inspect.getsourcefile(obj) or "").read_bytes()
    except (OSError, TypeError):
        return b""  # no source (a frozen build): the parameters and content still key it


def table_key(content: Iterable[np.ndarray], params: dict, code: Iterable[object]) -> str:
    """The digest of ``content`` (arrays, hashed with their dtype and shape), ``params`` and
    the source files of the ``code`` objects (modules or classes)."""
    digest = hashlib.blake2b(digest_size=20)
    for array in content:
        array = np.ascontiguousarray(array)
        digest.update(f"{array.dtype.str}{array.shape}".encode())
        digest.update(memoryview(array).cast("B"))
    digest.update(repr(sorted(params.items())).encode())
    for obj in code:
        digest.update(_source_text(obj))
    return digest.hexdigest()


def load(key: str, shape: tuple[int, int, int], floor: float) -> np.ndarray | None:
    """The stored density for ``key``, or None (absent, unreadable or not a valid density:
    ``shape``, finite, every value ≥ ``floor``·(1 − 1e-6))."""
    folder = cache_dir()
    if folder is None:
        return None
    path = folder / f"{key}.npy"
    if not path.is_file():
        return None
    try:
        density = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        return _reject(path, f"unreadable ({exc})")
    if density.dtype != np.float32 or density.shape != shape:
        return _reject(path, f"holds {density.dtype} {density.shape}, not float32 {shape}")
    if not np.all(np.isfinite(density)) or density.min() < floor * (1.0 - 1e-6):
        return _reject(path, "holds values that are no density (non-finite or below the floor)")
    stats["disk_hits"] += 1
    return density


def _reject(path: Path, why: str) -> None:
    stats["rejected"] += 1
    log.warning("importance table cache: %s %s; building it again", path.name, why)
    return None


def store(key: str, density: np.ndarray) -> None:
    """Keep ``density`` under ``key`` (failures logged once per folder, never raised: the
    cache only saves time)."""
    folder = cache_dir()
    if folder is None:
        return
    try:
        atomic_write(folder / f"{key}.npy", lambda fh: np.save(fh, density, allow_pickle=False))
        stats["stored"] += 1
    except OSError as exc:
        if str(folder) not in _warned:
            _warned.add(str(folder))
            log.warning(
                "importance table cache: cannot write in %s (%s); tables are built each "
                "session (set BTF_TABLE_CACHE to a writable folder, or 'off')",
                folder,
                exc.strerror or exc,
            )

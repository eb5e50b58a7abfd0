"""Arrays kept on disk between sessions under a key: the store behind the geometry cache
(scene/geometry_cache.py) and the World's pixels (blender/export/world_cache.py).

A file is ``<key>.npz`` (uncompressed: a read is a copy; the zip format's CRC-32 of every
array is checked as it is read). A file that fails to read (truncated, a changed byte: "Bad
CRC-32") or fails the caller's check is logged, rebuilt by the caller and replaced: a damaged
file costs time, never a wrong result.
When a store takes the folder past its cap the files used longest ago are removed first (a
read marks a file used), so the folder stays under the cap whatever is rendered. A folder that
cannot be written is logged once and the data built each time, as without a store. Writes are
atomic (core/fileio.py): a killed process never leaves a half-written file under a key.

Where: ``set_folder`` (Blender: the extension's user directory, removed with it), else the
store's environment variable (``off`` turns it off), else
``$XDG_CACHE_HOME/btf_materials/<subfolder>``.
"""

from __future__ import annotations

import logging
import os
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .fileio import atomic_write, user_cache_root

log = logging.getLogger(__name__)

OFF = "off"


class NpzStore:
    """One folder of keyed array files (module docstring)."""

    def __init__(self, what: str, env_var: str, subfolder: str, cap_bytes: int):
        self.what, self.env_var, self.subfolder = what, env_var, subfolder
        #: The folder's most bytes after a store.
        self.cap_bytes = cap_bytes
        self._folder_setting: Path | None = None
        self._warned: set[str] = set()
        self.stats = {"disk_hits": 0, "stored": 0, "rejected": 0, "evicted": 0}

    def set_folder(self, path: str | Path | None) -> None:
        """Keep files in ``path`` (None: back to the default, module docstring)."""
        self._folder_setting = Path(path) if path is not None else None

    def folder(self) -> Path | None:
        """The folder in use, None when the store is off."""
        if self._folder_setting is not None:
            return self._folder_setting
        env = os.environ.get(self.env_var)
        if env:
            return None if env.strip().lower() == OFF else Path(env)
        return user_cache_root() / "btf_materials" / self.subfolder

    def load(self, key: str, valid: Callable[[dict], bool]) -> dict | None:
        """The arrays stored under ``key``, or None (absent, unreadable, damaged, or not
        ``valid``)."""
        folder = self.folder()
        if folder is None:
            return None
        path = folder / f"{key}.npz"
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {name: data[name] for name in data.files}
        except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
            return self._reject(path, f"unreadable ({exc})")
        if not valid(arrays):
            return self._reject(path, "holds no valid data for this key")
        try:
            os.utime(path)  # recently used: the last to be evicted
        except OSError:
            pass
        self.stats["disk_hits"] += 1
        return arrays

    def _reject(self, path: Path, why: str) -> None:
        self.stats["rejected"] += 1
        log.warning("%s: %s %s; building it again", self.what, path.name, why)
        return None

    def store(self, key: str, arrays: dict) -> None:
        """Keep ``arrays`` under ``key`` (failures logged once per folder, never raised: the
        store only saves time), then keep the folder under the cap."""
        folder = self.folder()
        if folder is None:
            return
        try:
            atomic_write(folder / f"{key}.npz", lambda fh: np.savez(fh, **arrays))
            self.stats["stored"] += 1
            self._evict(folder, keep=f"{key}.npz")
        except OSError as exc:
            if str(folder) not in self._warned:
                self._warned.add(str(folder))
                log.warning(
                    "%s: cannot write in %s (%s); built each session instead (set %s to a "
                    "writable folder, or 'off')",
                    self.what,
                    folder,
                    exc.strerror or exc,
                    self.env_var,
                )

    def _evict(self, folder: Path, keep: str) -> None:
        """Remove the least recently used files until the folder holds at most the cap."""
        entries = []
        for path in folder.glob("*.npz"):
            try:
                info = path.stat()
            except OSError:
                continue  # removed by another process meanwhile
            entries.append((info.st_mtime, info.st_size, path))
        total = sum(size for _, size, _ in entries)
        for _, size, path in sorted(entries, key=lambda e: e[0]):
            if total <= self.cap_bytes:
                break
            if path.name == keep:
                continue
            try:
                path.unlink()
                self.stats["evicted"] += 1
            except OSError:
                pass  # another process's eviction got there first
            total -= size

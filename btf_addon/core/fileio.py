"""The one way files are written: into a temporary file beside the target, flushed to disk,
then renamed over it. A failed or interrupted write never leaves a half-written file under the
requested name, and an existing file stays intact until the new one is complete."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO


def atomic_write(path: str | Path, write: Callable[[BinaryIO], None]) -> Path:
    """Call ``write(fh)`` with a binary file object open on a temporary file in ``path``'s
    folder, then replace ``path`` with it. Creates the folder. Any exception (also
    KeyboardInterrupt) removes the temporary file and propagates."""
    return _atomic(Path(path), lambda tmp, fh: write(fh))


def atomic_write_path(path: str | Path, write: Callable[[Path], None]) -> Path:
    """For writers that insist on a file name (OpenEXR): ``write(tmp_path)`` fills a temporary
    file beside ``path``, which then replaces it, as ``atomic_write``."""
    return _atomic(Path(path), lambda tmp, fh: write(tmp))


def _atomic(path: Path, write: Callable[[Path, BinaryIO], None]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    # The suffix is kept last: np.save/np.savez and some image writers look at it.
    fd, name = tempfile.mkstemp(
        prefix=f".{path.stem}.", suffix=".tmp" + path.suffix, dir=path.parent
    )
    tmp = Path(name)
    try:
        with os.fdopen(fd, "r+b") as fh:
            write(tmp, fh)
            fh.flush()
            os.fsync(fh.fileno())  # what was written by name is the same inode: synced too
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path

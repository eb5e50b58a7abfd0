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
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # The suffix is kept last: np.save/np.savez and some image writers look at it.
    fd, tmp = tempfile.mkstemp(
        prefix=f".{path.stem}.", suffix=".tmp" + path.suffix, dir=path.parent
    )
    os.close(fd)  # reopened by name so that ``fh.name`` is the path (atomic_write_path uses it)
    try:
        with open(tmp, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_path(path: str | Path, write: Callable[[Path], None]) -> Path:
    """For writers that insist on a file name (OpenEXR): ``write(tmp_path)`` fills a temporary
    file beside ``path``, which then replaces it, as ``atomic_write``."""

    def through_name(fh: BinaryIO) -> None:
        write(Path(fh.name))
        fh.seek(0, os.SEEK_END)  # the writer wrote by name; nothing more through this handle

    return atomic_write(path, through_name)

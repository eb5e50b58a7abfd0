"""The one way files are written: into a temporary file beside the target, flushed to disk,
then renamed over it. A failed or interrupted write never leaves a half-written file under the
requested name, and an existing file stays intact until the new one is complete.

Temporary files are named ``.<stem>.pid<PID>-<host>.<random>.tmp<suffix>``: the writer's process
id and machine are in the name, so a later write to the same target on the same machine removes
the leftovers of writers that were killed (SIGKILL, power loss) and whose process is gone.
The output gets the permissions any other new file would (``0666 & ~umask``), not mkstemp's
private 0600.
"""

from __future__ import annotations

import errno
import logging
import os
import re
import secrets
import socket
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from .errors import BTFError

log = logging.getLogger(__name__)


def atomic_write(path: str | Path, write: Callable[[BinaryIO], None]) -> Path:
    """Call ``write(fh)`` with a binary file object open on a temporary file in ``path``'s
    folder, then replace ``path`` with it. Creates the folder. Any exception (also
    KeyboardInterrupt) removes the temporary file and propagates."""
    return _atomic(Path(path), lambda tmp, fh: write(fh))


def atomic_write_path(path: str | Path, write: Callable[[Path], None]) -> Path:
    """For writers that insist on a file name (OpenEXR): ``write(tmp_path)`` fills a temporary
    file beside ``path``, which then replaces it, as ``atomic_write``."""
    return _atomic(Path(path), lambda tmp, fh: write(tmp))


def user_cache_root() -> Path:
    """Where per-user caches go: ``$XDG_CACHE_HOME``, else ``~/.cache`` (read each call: the
    OpenCL set-up may point it elsewhere when it cannot be written)."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")


def _host() -> str:
    """This machine's name as it may appear in a file name: a shared folder (NFS) seen from
    several machines must not have one machine judge another's process ids."""
    return re.sub(r"[^A-Za-z0-9-]", "", socket.gethostname())[:32] or "host"


def temp_prefix(path: Path) -> str:
    """The start of every temporary file name this process uses for ``path``."""
    return f".{path.stem}.pid{os.getpid()}-{_host()}."


def current_umask() -> int:
    """The process umask, read without changing it where the system allows (Linux exposes it
    in /proc; elsewhere it is set and restored at once)."""
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # exists but belongs to someone else (or unknowable): leave its file
    return True


def remove_stale_temporaries(path: Path) -> list[Path]:
    """Delete temporaries for ``path`` left by writers whose process no longer exists.

    Only names of our own pattern written on this machine (``.<stem>.pid<N>-<host>.*.tmp<suffix>``)
    are considered; a file of a live process (a concurrent writer) is left alone. Returns the
    files removed."""
    pattern = re.compile(
        re.escape(f".{path.stem}.pid")
        + r"(\d+)-"
        + re.escape(_host())
        + r"\.[^/]*\.tmp"
        + re.escape(path.suffix)
        + "$"
    )
    removed = []
    try:
        entries = list(path.parent.iterdir())
    except OSError:
        return removed
    for entry in entries:
        m = pattern.match(entry.name)
        if m and not _pid_alive(int(m.group(1))):
            try:
                entry.unlink()
                removed.append(entry)
                log.info("removed a stale temporary file %s", entry)
            except OSError:
                pass  # another writer cleaned it first, or the folder is read-only
    return removed


def check_output(path: str | Path) -> Path:
    """Refuse, before any work is done, an output ``atomic_write`` could not put in place: a
    folder, a parent that is a file, or a folder this process cannot create a file in
    (permissions, a read-only file system: probed by creating and removing a temporary file
    there). BTFError naming the output; ``path`` itself when it can be written."""
    path = Path(path)
    if path.is_dir():
        raise BTFError(f"{path}: is a folder; name the file to write (for example {path / 'out'})")
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent  # atomic_write creates the missing folders below this one
    if not folder.is_dir():
        raise BTFError(f"{path}: cannot be written: {folder} is a file, not a folder")
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise BTFError(f"{path}: cannot write in {folder}: {exc.strerror or exc}") from None
    return path


def _atomic(path: Path, write: Callable[[Path, BinaryIO], None]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(path)
    tmp: Path | None = None
    try:
        # The temporary's name is chosen before the file is made, inside the ``try``: a Ctrl-C
        # or SIGTERM the moment it exists still finds the cleanup below knowing its name
        # (mkstemp's name arrives only after the file exists; another thread may take the
        # signal, so holding signals back in this one would not close that gap).
        flags = os.O_RDWR | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)
        for _ in range(100):
            tmp = temporary_name(path)
            try:
                fd = os.open(tmp, flags, 0o600)  # private until its mode is set below
                break
            except FileExistsError:
                tmp = None  # another writer's (2^-64 per try): never ours to remove
        else:
            raise FileExistsError(errno.EEXIST, "no free temporary file name", str(path))
        os.chmod(fd if os.chmod in os.supports_fd else tmp, 0o666 & ~current_umask())
        with os.fdopen(fd, "r+b") as fh:
            write(tmp, fh)
            fh.flush()
            os.fsync(fh.fileno())  # what was written by name is the same inode: synced too
        os.replace(tmp, path)
    except OSError as exc:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        if exc.filename in (None, str(tmp), tmp):
            # A full disk or a refused rename: say the output, not our temporary name.
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
        raise
    except BaseException:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        raise
    return path


def temporary_name(path: Path) -> Path:
    """A fresh temporary name beside ``path``: ``temp_prefix`` + random + ``.tmp`` + the suffix
    (kept last: np.save/np.savez and some image writers look at it)."""
    return path.parent / f"{temp_prefix(path)}{secrets.token_hex(8)}.tmp{path.suffix}"

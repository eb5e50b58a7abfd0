"""Recordings of a controller session: the JSONL format, a replay transport and a recorder.

Format (one JSON object per line, UTF-8, lines in time order)::

    {"t": 0.000, "dir": "out", "hex": "1110"}
    {"t": 0.012, "dir": "in",  "hex": "20000012000064"}

- ``t``: seconds (float) since the start of the session; non-decreasing.
- ``dir``: ``"in"`` (device → host, an input report) or ``"out"`` (host → device, an output
  report the driver wrote).
- ``hex``: the whole report as hex digits (spaces allowed), first byte the report id.
Blank lines and lines starting with ``#`` are comments. Readers also accept ``time`` or
``timestamp`` for ``t``, ``direction`` for ``dir``, ``data``, ``bytes`` or ``report`` for
``hex``, and any letter case in the values (``"IN"``); writers use the names above.

A replay plays the ``in`` lines to the driver and records what the driver writes (the ``out``
lines of the file are what the recording driver wrote: kept for comparison, never played).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from .transport import ControllerDisconnectedError, ControllerError, Transport

IN = "in"
OUT = "out"


@dataclass(frozen=True)
class Record:
    """One line of a recording: ``t`` seconds, ``direction`` IN or OUT, ``data`` the report."""

    t: float
    direction: str
    data: bytes

    def to_json(self) -> str:
        return json.dumps({"t": round(self.t, 6), "dir": self.direction, "hex": self.data.hex()})


def _field(obj: dict, *names: str):
    for name in names:
        if name in obj:
            return obj[name]
    raise KeyError(names[0])


def parse_line(line: str, where: str = "recording") -> Record | None:
    """One line → a Record, None for a blank or comment line. Raises ControllerError naming
    ``where`` on a malformed line."""
    text = line.strip()
    if not text or text.startswith("#"):
        return None
    try:
        obj = json.loads(text)
        t = float(_field(obj, "t", "time", "timestamp"))
        direction = str(_field(obj, "dir", "direction")).lower()
        data = bytes.fromhex(str(_field(obj, "hex", "data", "bytes", "report")).replace(" ", ""))
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ControllerError(f"{where}: not a report line ({exc}): {text[:80]!r}") from exc
    if direction not in (IN, OUT):
        raise ControllerError(f"{where}: dir must be 'in' or 'out', not {direction!r}")
    if not data:
        raise ControllerError(f"{where}: empty report")
    return Record(t, direction, data)


def load(path: str | Path) -> list[Record]:
    """All records of a JSONL recording, checked for non-decreasing time."""
    records = []
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            record = parse_line(line, f"{path}:{number}")
            if record is None:
                continue
            if records and record.t < records[-1].t:
                raise ControllerError(f"{path}:{number}: time goes backwards ({record.t})")
            records.append(record)
    return records


def dump(records: list[Record], path: str | Path) -> None:
    Path(path).write_text("".join(r.to_json() + "\n" for r in records), encoding="utf-8")


class ReplayTransport:
    """Plays the ``in`` reports of a recording and keeps what the driver writes.

    ``realtime=False`` (tests): every ``read`` returns the next report at once and ``now()`` is
    its timestamp. ``realtime=True`` (the operator in a live Blender): a report is returned only
    once its timestamp has passed on the monotonic clock since the first read. When the reports
    run out, ``read`` raises ``ControllerDisconnectedError`` (as a device that vanished).
    ``written``: the driver's output reports as Records stamped with the replay's ``now()``.
    """

    def __init__(self, records: list[Record], *, realtime: bool = False) -> None:
        self._inputs = [r for r in records if r.direction == IN]
        self._next = 0
        self._now = self._inputs[0].t if self._inputs else 0.0
        self._realtime = realtime
        self._start_clock: float | None = None
        self._closed = False
        self.written: list[Record] = []

    @classmethod
    def from_file(cls, path: str | Path, *, realtime: bool = False) -> ReplayTransport:
        return cls(load(path), realtime=realtime)

    @property
    def remaining(self) -> int:
        return len(self._inputs) - self._next

    def write(self, data: bytes) -> None:
        if self._closed:
            raise ControllerDisconnectedError("the replay was closed")
        self.written.append(Record(self._now, OUT, bytes(data)))

    def read(self, timeout_s: float) -> bytes | None:
        if self._closed:
            raise ControllerDisconnectedError("the replay was closed")
        if self._next >= len(self._inputs):
            raise ControllerDisconnectedError("the recording ended")
        record = self._inputs[self._next]
        if self._realtime:
            clock = time.monotonic()
            if self._start_clock is None:
                self._start_clock = clock - record.t
            if record.t > clock - self._start_clock + max(timeout_s, 0.0):
                return None
        self._next += 1
        self._now = record.t
        return record.data

    def now(self) -> float:
        return self._now

    def close(self) -> None:
        self._closed = True


class RecordingTransport:
    """Wraps a transport and writes every report in and out to a JSONL file (the format above),
    with ``t`` relative to the first report: a user's session for a bug report. Owns ``inner``:
    ``close`` closes it, and so does a file that cannot be opened (ControllerError)."""

    def __init__(self, inner: Transport, out: str | Path | TextIO) -> None:
        self._inner = inner
        self._owns = isinstance(out, str | Path)
        if self._owns:
            try:
                out = open(out, "w", encoding="utf-8")
            except OSError as exc:  # the device is open: release it, say what to change
                inner.close()
                raise ControllerError(
                    f"cannot write the session recording {out} ({exc.strerror or exc}): save "
                    "the .blend in a writable folder or turn off Record Sessions"
                ) from exc
        self._file = out
        self._t0: float | None = None

    def _log(self, direction: str, data: bytes) -> None:
        now = self._inner.now()
        if self._t0 is None:
            self._t0 = now
        self._file.write(Record(now - self._t0, direction, bytes(data)).to_json() + "\n")
        self._file.flush()  # a crash must leave the session on disk

    def write(self, data: bytes) -> None:
        self._inner.write(data)
        self._log(OUT, data)

    def read(self, timeout_s: float) -> bytes | None:
        data = self._inner.read(timeout_s)
        if data is not None:
            self._log(IN, data)
        return data

    def now(self) -> float:
        return self._inner.now()

    def close(self) -> None:
        try:
            self._inner.close()
        finally:
            if self._owns:
                self._file.close()

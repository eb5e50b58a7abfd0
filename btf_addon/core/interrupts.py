"""Ctrl-C and SIGTERM held back where stopping half-way would leave a mess: while the XTAL
bridge changes the OpenXR protocol's state, while ``import bpy`` runs Blender's start-up (a
half-started Blender segfaulted on exit), while a capture frame is written.

Python raises KeyboardInterrupt between any two bytecodes of the main thread: between
xrBeginSession and the flag that says the session runs, between xrAcquireSwapchainImage and
its release, half-way through a teardown. A teardown that then skips its last steps leaves a
frame begun, a running session, pending GL work or a live XrInstance, and a runtime (Monado)
crashes, or the OpenXR loader refuses the next instance (issue 30 item 1). So the bridge runs
each protocol step — the session's creation, its events, one frame from xrWaitFrame to
xrEndFrame, the teardown — inside ``deferred()``: a signal arriving there is recorded and
delivered, to the handler that was installed, when the outermost block ends, i.e. at a point
where the protocol is consistent. The frame's long part, drawing an eye into the acquired
image, runs inside ``allowed()``: Ctrl-C lands at once, and the frame's own cleanup (release
the image, end the frame with no layers) runs before it leaves the frame.

Signals reach Python in the main thread only: elsewhere (the Blender operator's worker
thread) both blocks do nothing. A signal is never lost: whichever handler is installed at any
moment, ours records it while a block is active and passes it to the previous one otherwise.
"""

from __future__ import annotations

import os
import signal
import threading

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class _Deferral:
    """The main thread's state: ``depth`` of nested ``deferred`` blocks, ``allowing``: the
    depths at which ``allowed`` blocks were entered (innermost last; signals are held only in
    ``deferred`` blocks opened inside the innermost), the ``pending`` signals recorded, the
    handlers ours replaced."""

    def __init__(self) -> None:
        self.depth = 0
        self.allowing: list[int] = []
        self.pending: list[int] = []
        self.previous: dict[int, object] = {}

    def base(self) -> int:
        """The depth at and below which signals land at once (the innermost ``allowed``)."""
        return self.allowing[-1] if self.allowing else 0

    def holding(self) -> bool:
        return self.depth > self.base()


_state = _Deferral()


def _handler(signum, frame) -> None:
    if _state.holding():
        _state.pending.append(signum)
    else:  # between blocks (or inside allowed()): as if we were not installed
        _call_previous(signum, frame)


def _call_previous(signum: int, frame=None) -> None:
    previous = _state.previous.get(signum, signal.SIG_DFL)
    if callable(previous):
        previous(signum, frame)
    elif previous == signal.SIG_IGN:
        return
    elif signum == signal.SIGINT:
        raise KeyboardInterrupt
    else:  # the default action of SIGTERM: the process ends by the signal
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _install() -> None:
    for signum in SIGNALS:
        current = signal.getsignal(signum)
        # None: a host's handler not installed from Python (it could not be put back): left
        # alone, that signal is not held back.
        if current is not _handler and current is not None:
            _state.previous[signum] = current
            signal.signal(signum, _handler)


def _uninstall() -> None:
    for signum in SIGNALS:
        if signal.getsignal(signum) is _handler:
            signal.signal(signum, _state.previous.get(signum, signal.SIG_DFL))


def _deliver(exc: BaseException | None) -> None:
    """The recorded signals, SIGTERM first (cli/main.py's precedence), unless the exception
    already leaving says the same (a KeyboardInterrupt for a SIGINT)."""
    pending, _state.pending = _state.pending, []
    for signum in (signal.SIGTERM, signal.SIGINT):
        if signum not in pending:
            continue
        if signum == signal.SIGINT and isinstance(exc, KeyboardInterrupt):
            continue
        if signum == signal.SIGTERM and type(exc).__name__ == "Terminated":
            continue
        _call_previous(signum)


class deferred:  # noqa: N801 - used as a function: ``with deferred():``
    """Hold Ctrl-C and SIGTERM back in the block (module docstring); nested blocks hold them
    until the outermost ends, which then delivers them to the handlers installed before. A
    block inside ``allowed`` (a shader compiled while an eye draws) holds them too and
    delivers them at its end, into the ``allowed`` block; our handler stays installed for
    the ``deferred`` blocks around it. Depths are restored as absolute values: an interrupt
    inside an inner block's exit leaves the outer blocks' counts right."""

    def __enter__(self) -> deferred:
        self._outer_depth = None
        if not _main_thread():
            return self
        self._outer_depth = _state.depth
        _state.depth = self._outer_depth + 1
        if self._outer_depth == 0:
            try:
                _install()
            except BaseException:  # a signal before ours was in place: nothing held yet
                _state.depth = 0
                _uninstall()
                raise
        return self

    def __exit__(self, _type, exc, _tb) -> bool:
        if self._outer_depth is None:
            return False
        _state.depth = self._outer_depth
        while _state.allowing and _state.allowing[-1] > _state.depth:
            _state.allowing.pop()  # an allowed() inside left by an interrupt in its exit
        if self._outer_depth == 0:
            _uninstall()
            _deliver(exc)
        elif not _state.holding():  # back in an allowed() block: what was held lands now
            _deliver(exc)
        return False


class allowed:  # noqa: N801 - used as a function: ``with allowed():``
    """Inside ``deferred``: Ctrl-C and SIGTERM land at once in this block (one recorded
    before it lands as it starts); held back again after it."""

    def __enter__(self) -> allowed:
        self._entered = False
        if not _main_thread() or not _state.holding():
            return self
        _state.allowing.append(_state.depth)
        self._entered = True
        try:
            _deliver(None)
        except BaseException:
            self._leave()
            raise
        return self

    def _leave(self) -> None:
        if self._entered:
            self._entered = False
            _state.allowing.pop()

    def __exit__(self, *_exc) -> bool:
        self._leave()
        return False


def pending() -> list[int]:
    """The signals recorded and not yet delivered (for tests)."""
    return list(_state.pending)

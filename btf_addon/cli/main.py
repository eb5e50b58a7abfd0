"""Argument parsing and the one error boundary shared by all commands.

Every failure ends as one line on stderr and an exit code: each error of the add-on's one root
(core/errors.py ``BTFMaterialsError``) its own ``exit_code`` — 2 for input or a device the
user can fix (``BTFError``, including ``MemoryLimitError`` for sizes refused up front;
``DeviceError``), the bridge's 3–6 (xr/errors.py) — 2 for ``OSError`` (a missing file, a full
disk), 1 for an internal error ("internal error: …, rerun with -v"; ``-v``
prints the traceback), 130 for Ctrl-C and SIGTERM. Interrupts unwind through the writers,
so ``core/fileio.py`` removes its temporary files on the way out.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import traceback

from ..core import memory
from ..core.errors import BTFMaterialsError
from ..core.interrupts import deferred

EXIT_INPUT = 2
EXIT_INTERNAL = 1
EXIT_INTERRUPTED = 130


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C so every ``finally`` and cleanup runs."""


#: Signals received during this command, in order: code that runs callbacks which swallow
#: exceptions (Blender's render engine reports one and carries on saving) checks it after.
signals_received: list[int] = []


def _on_sigterm(signum, _frame) -> None:
    signals_received.append(signum)
    raise Terminated(f"signal {signum}")


def _on_sigint(signum, frame) -> None:
    signals_received.append(signum)
    signal.default_int_handler(signum, frame)


def signals_held():
    """Ctrl-C and SIGTERM recorded but not raised inside the block, raised when it ends
    (core/interrupts.py ``deferred``: delivered to this module's handlers then). For work that
    must not stop halfway: ``import bpy`` runs Blender's start-up (its own add-ons register
    classes), and an interrupt there left a half-registered Blender that segfaulted on the way
    out; so did one inside our add-on's register/unregister."""
    return deferred()


def raise_if_interrupted() -> None:
    """Re-raise a Ctrl-C or SIGTERM that a callback swallowed (see ``signals_received``)."""
    if signal.SIGTERM in signals_received:
        raise Terminated(f"signal {signal.SIGTERM}")
    if signal.SIGINT in signals_received:
        raise KeyboardInterrupt


def build_parser(prog: str = "python -m btf_addon") -> argparse.ArgumentParser:
    from . import (
        accuracy_command,
        bake_command,
        bridge_command,
        btf_commands,
        compress_command,
        doctor,
        envmap_command,
        render_command,
    )

    parser = argparse.ArgumentParser(prog=prog, description="BTF Materials command-line tools")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="log progress; tracebacks of internal errors"
    )
    parser.add_argument(
        "--max-memory",
        metavar="SIZE",
        help="refuse work whose estimated peak memory exceeds SIZE (e.g. 4G); default: what "
        "the machine has available (also BTF_MEMORY_LIMIT)",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("doctor", help="report what this machine offers the add-on (JSON)")
    p.set_defaults(func=doctor.main)
    btf_commands.add_parsers(sub)
    envmap_command.add_parser(sub)
    render_command.add_parser(sub)
    bridge_command.add_parser(sub)
    accuracy_command.add_parser(sub)
    bake_command.add_parser(sub)
    compress_command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None, prog: str = "python -m btf_addon") -> int:
    """Run one command; ``prog`` names the program in usage lines (``blender --command btf``
    when Blender runs it: cli/blender_command.py)."""
    given = argv if argv is not None else sys.argv[1:]
    verbose = "-v" in given or "--verbose" in given
    previous = _install_sigterm()
    try:
        return _run(argv, prog)
    except KeyboardInterrupt as exc:
        what = "terminated" if isinstance(exc, Terminated) else "interrupted"
        print(f"{what}: stopped, partial outputs removed", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BTFMaterialsError as exc:  # every error raised on purpose, with its exit status
        print(f"error: {exc}", file=sys.stderr)
        return exc.exit_code
    except OSError as exc:
        print(f"error: {_os_error_text(exc)}", file=sys.stderr)
        return EXIT_INPUT
    except MemoryError:
        if verbose:
            traceback.print_exc()
        print(
            "error: out of memory (the up-front estimate missed this case; rerun with -v and "
            "report it, or use a smaller size)",
            file=sys.stderr,
        )
        return EXIT_INTERNAL
    except Exception as exc:
        if verbose:
            traceback.print_exc()
        text = str(exc).strip().splitlines()
        detail = f": {text[0]}" if text else ""
        print(
            f"internal error: {type(exc).__name__}{detail} (a bug: rerun with -v for the "
            "traceback and report it)",
            file=sys.stderr,
        )
        return EXIT_INTERNAL
    finally:
        _restore_sigterm(previous)


def _run(argv: list[str] | None, prog: str) -> int:
    parser = build_parser(prog)
    args, extra = parser.parse_known_args(argv)
    if extra and not getattr(args, "accepts_params", False):
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    args.extra = extra
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    memory.set_limit(memory.parse_size(args.max_memory) if args.max_memory else None)
    return args.func(args)


def _os_error_text(exc: OSError) -> str:
    """``[Errno 2] No such file or directory: 'x'`` → ``x: No such file or directory``."""
    if exc.filename is not None and exc.strerror:
        return f"{exc.filename}: {exc.strerror}"
    return str(exc) or type(exc).__name__


def _install_sigterm():
    """SIGTERM → ``Terminated``, SIGINT → KeyboardInterrupt, both recorded, in the main thread
    (elsewhere signals cannot be handled)."""
    signals_received.clear()
    try:
        return (
            signal.signal(signal.SIGTERM, _on_sigterm),
            signal.signal(signal.SIGINT, _on_sigint),
        )
    except ValueError:  # not the main thread (an embedding host)
        return None


def _restore_sigterm(previous) -> None:
    if previous is not None:
        signal.signal(signal.SIGTERM, previous[0])
        signal.signal(signal.SIGINT, previous[1])

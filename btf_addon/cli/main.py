"""Argument parsing and error handling shared by all commands."""

from __future__ import annotations

import argparse
import logging
import sys

from ..core.errors import BTFError


def build_parser() -> argparse.ArgumentParser:
    from . import (
        accuracy_command,
        bridge_command,
        btf_commands,
        doctor,
        envmap_command,
        render_command,
    )

    parser = argparse.ArgumentParser(
        prog="python -m btf_addon", description="BTF Materials command-line tools"
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress to stderr")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("doctor", help="report what this machine offers the add-on (JSON)")
    p.set_defaults(func=doctor.main)
    btf_commands.add_parsers(sub)
    envmap_command.add_parser(sub)
    render_command.add_parser(sub)
    bridge_command.add_parser(sub)
    accuracy_command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and not getattr(args, "accepts_params", False):
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    args.extra = extra
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return args.func(args)
    except BTFError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

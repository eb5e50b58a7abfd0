"""Rewrite the measured sections of docs/accuracy.md from the benchmarks' output.

docs/accuracy.md is the current reference: its prose is written by hand, its measured tables
are generated. A measured section is

    <!-- bench:KEY -->
    *Measured DATE; regenerate with `COMMAND`.*

    OUTPUT
    <!-- /bench:KEY -->

KEY names a benchmark module of benchmarks/ and the arguments it ran with (``bench_decode``,
``bench_compress_svd --real alu wallpaper --no-synthetic``); OUTPUT is what its ``main()``
returned, verbatim. Only what lies between a section's two markers is ever rewritten.

``make bench`` (run_all.py) runs the MAKE_BENCH benchmarks and rewrites each one's section as
it finishes. The other sections are slow or need a Blender with Cycles, and are rerun by hand,
one at a time:

    python benchmarks/write_reference.py bench_compress_svd --real alu wallpaper --no-synthetic

runs that benchmark with those arguments, prints its output and rewrites the section whose key
is exactly that. bench_accuracy writes its own section (between its BEGIN/END markers) and its
figures in docs/accuracy_bench/. What a rerun replaces is kept by git; readings that a new run
no longer supports move, dated, to docs/accuracy-history.md.
"""

from __future__ import annotations

import datetime
import importlib
import inspect
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "accuracy.md"

#: What `make bench` runs, in order. bench_accuracy last: it rewrites its own section.
MAKE_BENCH = (
    "bench_decode",
    "bench_interpolation",
    "bench_envmap",
    "bench_viewport",
    "bench_vr",
    "bench_bridge",
    "bench_final_render",
    "bench_mapping",
    "bench_aa",
    "bench_specialise",
    "bench_btf_importance",
    "bench_wiimote",
    "bench_formats",
    "bench_compress_svd",  # synthetic only; the real materials by hand (their own section)
    "bench_accuracy",
)
#: Benchmarks that write their part of the document themselves.
SELF_WRITTEN = ("bench_accuracy",)

SECTION = re.compile(
    r"^<!-- bench:(?P<key>[^\n]*?) -->\n(?P<body>.*?)^<!-- /bench:(?P=key) -->$", re.S | re.M
)
STAMP = re.compile(
    r"\*Measured (?P<date>\d{4}-\d{2}-\d{2}); regenerate with `(?P<command>[^`]+)`\.\*"
)
#: The body of a section no run has written yet.
NOT_YET = "*Not measured yet: `make bench` writes this section.*\n"


def keys(text: str) -> list[str]:
    """The keys of the measured sections in ``text``, in order."""
    return [m["key"] for m in SECTION.finditer(text)]


def benchmark(key: str) -> tuple[str, list[str]]:
    """(module name, argv) of a section key."""
    name, *argv = key.split()
    return name, argv


def command(key: str) -> str:
    """The command that regenerates a section."""
    if key in MAKE_BENCH:
        return "make bench"
    return f"python benchmarks/write_reference.py {key}"


def body(key: str, output: str, date: str) -> str:
    """A section's text between its markers: the stamp, then the output as printed."""
    return f"*Measured {date}; regenerate with `{command(key)}`.*\n\n{output.strip()}\n"


def rewrite(text: str, outputs: dict[str, str], date: str) -> tuple[str, list[str]]:
    """``text`` with the section of every key in ``outputs`` replaced by its output; the keys
    rewritten. Text outside those sections is returned unchanged, byte for byte."""
    done = []

    def replace(m: re.Match) -> str:
        key = m["key"]
        if key not in outputs:
            return m[0]
        done.append(key)
        return f"<!-- bench:{key} -->\n{body(key, outputs[key], date)}<!-- /bench:{key} -->"

    return SECTION.sub(replace, text), done


def write(outputs: dict[str, str], doc: Path = DOC, date: str | None = None) -> list[str]:
    """Rewrite the sections of ``outputs`` in ``doc`` (read afresh: another benchmark may have
    written it since); the keys rewritten."""
    date = date or datetime.date.today().isoformat()
    text = doc.read_text(encoding="utf-8")
    new, done = rewrite(text, outputs, date)
    if new != text:
        doc.write_text(new, encoding="utf-8")
    return done


def run(key: str) -> str:
    """Run one benchmark as a section key names it; its output."""
    name, argv = benchmark(key)
    module = importlib.import_module(name)
    if "argv" in inspect.signature(module.main).parameters:
        return module.main(argv)  # even when empty: its parser must not read our sys.argv
    if argv:
        raise SystemExit(f"{name}.main() takes no command-line arguments")
    return module.main()


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__)
        return 2
    key = " ".join(argv)
    if key not in keys(DOC.read_text(encoding="utf-8")):
        print(f"note: docs/accuracy.md has no section `bench:{key}`: printing only", flush=True)
    output = run(key)
    print(output)
    if write({key: output}):
        print(f"\n(rewrote the section `bench:{key}` of docs/accuracy.md)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

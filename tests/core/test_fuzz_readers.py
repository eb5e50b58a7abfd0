"""Fuzzing every reader through the command line's own entry point (``cli.main.main``, in
process): a damaged input must end in exit 0 (read) or 2 (refused with one line), never 1
(an internal error: a traceback with -v), never hang, and never allocate (traced by
tracemalloc, which sees numpy's buffers) beyond the command's memory estimate.

A reader is one entry in ``READERS``: how to write a valid seed input, the command that reads
it, how to mutate it, and its memory estimate. Each entry runs a fixed number of mutations
from a fixed seed, so a failure reproduces by its case number.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import struct
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from helpers import shared_material

from btf_addon.cli.main import main
from btf_addon.core import memory
from btf_addon.core.codecs.analytic import LambertianBTF, PrincipledBTF
from btf_addon.core.codecs.dense import tabulate
from btf_addon.core.codecs.microgeometry import leather
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.codecs.svd_build import factorise
from btf_addon.core.formats import container
from btf_addon.core.formats.imageio import write_exr
from btf_addon.core.formats.ubo2014_writer import write_ubo2014
from btf_addon.core.grid import UBO2003, uniform_ring_grid

#: Seconds one case may take before it counts as a hang (the slowest valid read here, the
#: BTFbase text of alu under tracemalloc, takes about 1 s).
HANG_SECONDS = 30
#: Allocation slack above an estimate: Python objects of the command itself (argparse, the
#: JSON of info) that the per-command models do not count.
SLACK_BYTES = 32 * memory.MIB
#: Mutations per reader are ``count`` × this (BTF_FUZZ_SCALE=10 for a longer run by hand; CI
#: runs the fixed counts, about 30 s in all).
SCALE = int(os.environ.get("BTF_FUZZ_SCALE", "1"))


@dataclass(frozen=True)
class Reader:
    """``seed(folder) -> input path``; ``mutate(path, rng)`` damages it in place;
    ``argv(path, out_folder)`` the command; ``estimate(path)`` its peak bytes; ``count``
    mutations per run."""

    name: str
    seed: Callable[[Path], Path]
    mutate: Callable[[Path, np.random.Generator], None]
    argv: Callable[[Path, Path], list[str]]
    estimate: Callable[[Path], int]
    count: int


# --- generic mutations -------------------------------------------------------------------
NASTY_TOKENS = [b"nan", b"-inf", b"-1", b"0", b"1e308", b"99999999999999999999", b"x", b"", b"-0"]


def mutate_bytes(path: Path, rng: np.random.Generator) -> None:
    """Flip, truncate, insert or duplicate bytes."""
    data = bytearray(path.read_bytes())
    kind = rng.integers(4)
    at = int(rng.integers(len(data) + 1))
    if kind == 0 and data:
        for i in rng.integers(0, len(data), size=int(rng.integers(1, 9))):
            data[int(i)] ^= 1 << int(rng.integers(8))
    elif kind == 1:
        del data[at:]
    elif kind == 2:
        data[at:at] = rng.integers(0, 256, size=int(rng.integers(1, 64)), dtype=np.uint8).tobytes()
    else:
        data[at:at] = data[at : at + int(rng.integers(1, 256))]
    path.write_bytes(bytes(data))


def mutate_text(path: Path, rng: np.random.Generator) -> None:
    """Token-level damage to a whitespace-separated table: a nasty token, a line dropped or
    doubled, the file cut anywhere (also inside a number)."""
    lines = path.read_bytes().split(b"\n")
    kind = rng.integers(4)
    i = int(rng.integers(len(lines)))
    if kind == 0:
        tokens = lines[i].split()
        if tokens:
            tokens[int(rng.integers(len(tokens)))] = NASTY_TOKENS[rng.integers(len(NASTY_TOKENS))]
            lines[i] = b" ".join(tokens)
    elif kind == 1:
        del lines[i]
    elif kind == 2:
        lines.insert(i, lines[i])
    else:
        data = b"\n".join(lines)
        path.write_bytes(data[: int(rng.integers(len(data) + 1))])
        return
    path.write_bytes(b"\n".join(lines))


# --- BTFbase text ------------------------------------------------------------------------
def btfbase_seed(folder: Path) -> Path:
    """The text tables alone: with ``binary.btf`` beside them a damaged table falls back to it."""
    dst = folder / "alu"
    shutil.copytree(shared_material("alu"), dst)
    (dst / "binary.btf").unlink(missing_ok=True)
    return dst


# --- BTFbase binary.btf --------------------------------------------------------------------
def btfbase_binary_seed(folder: Path) -> Path:
    """A material folder holding only ``binary.btf`` (as some of the thesis gallery's)."""
    dst = folder / "alu"
    dst.mkdir()
    shutil.copy(shared_material("alu") / "binary.btf", dst / "binary.btf")
    return dst


def btfbase_binary_mutate(path: Path, rng: np.random.Generator) -> None:
    mutate_bytes(path / "binary.btf", rng)


# --- UBO2014 DFMF .btf ---------------------------------------------------------------------
def ubo2014_seed(folder: Path) -> Path:
    btf, _errors = factorise(
        tabulate(LambertianBTF((0.8, 0.5, 0.2)), UBO2003, UBO2003, width=2, height=2).data * np.pi,
        ranks=(2, 1, 1),
        name="fuzz",
    )
    write_ubo2014(folder / "m.btf", btf)
    return folder / "m.btf"


def btfbase_mutate(path: Path, rng: np.random.Generator) -> None:
    files = sorted(p for p in path.iterdir() if p.suffix == ".txt")
    mutate_text(files[int(rng.integers(len(files)))], rng)


# --- .btfm container ---------------------------------------------------------------------
#: One container per codec family: each codec's ``from_params`` sees the damaged header.
BTFM_SEEDS: dict[str, Callable[[], object]] = {
    "dense": lambda: tabulate(
        LambertianBTF((0.8, 0.5, 0.2)), uniform_ring_grid(30.0), uniform_ring_grid(30.0)
    ),
    "mlvq": lambda: MLVQBTF.from_directory(shared_material("alu")),
    "microgeometry": lambda: leather(texels=4, fine_per_texel=4),
    "principled": lambda: PrincipledBTF(),
}


def btfm_seed(codec: str) -> Callable[[Path], Path]:
    return lambda folder: container.write_container(folder / "m.btfm", BTFM_SEEDS[codec]())


def _rewrite_header(path: Path, edit: Callable[[dict], object]) -> None:
    """Change the JSON header and write a valid checksum: damage the checksum cannot see."""
    blob = path.read_bytes()
    fixed = len(container.MAGIC) + 8
    _version, head_len = struct.unpack_from("<II", blob, len(container.MAGIC))
    header = json.loads(blob[fixed : fixed + head_len])
    start = fixed + head_len + (-(fixed + head_len)) % container.ALIGN
    body = blob[start : len(blob) - 40]
    text = json.dumps(edit(header)).encode()
    prefix = container.MAGIC + struct.pack("<II", container.FORMAT_VERSION, len(text)) + text
    prefix += b"\0" * ((-len(prefix)) % container.ALIGN)
    data = prefix + body
    path.write_bytes(data + hashlib.sha256(data).digest() + container.END_MAGIC)


NASTY_VALUES = [None, -1, 0, 2**63, 2**64 + 7, -(2**70), 1.5, "7", [], {}, [3, -3], [2**40] * 3,
                True, "x" * 100]  # fmt: skip


def btfm_mutate(path: Path, rng: np.random.Generator) -> None:
    if rng.random() < 0.25:
        mutate_bytes(path, rng)  # the checksum's part
        return

    def edit(header):
        # A random path into the header (objects and lists alike), its value replaced.
        node, parent, key = header, None, None
        for _ in range(int(rng.integers(1, 4))):
            if not isinstance(node, (dict, list)) or not node:
                break
            keys = list(node) if isinstance(node, dict) else list(range(len(node)))
            parent, key = node, keys[int(rng.integers(len(keys)))]
            node = parent[key]
            if rng.random() < 0.3:
                break
        if parent is not None:
            parent[key] = NASTY_VALUES[int(rng.integers(len(NASTY_VALUES)))]
        return header

    _rewrite_header(path, edit)


# --- EXR environment ---------------------------------------------------------------------
def exr_seed(folder: Path) -> Path:
    image = np.random.default_rng(3).random((16, 32, 3)).astype(np.float32)
    return write_exr(folder / "env.exr", image)


# --- .npy queries --------------------------------------------------------------------------
DTYPES = [b"'<f4'", b"'<c8'", b"'|b1'", b"'|O'", b"'<U3'", b"'>f8'", b"'<f2'", b"'<i8'", b"'|V4'"]


def npy_seed(folder: Path) -> Path:
    q = np.random.default_rng(4).random((64, 6)).astype(np.float32) * 90
    q[::7, 2] = np.nan
    np.save(folder / "q.npy", q)
    return folder / "q.npy"


def npy_mutate(path: Path, rng: np.random.Generator) -> None:
    data = path.read_bytes()
    kind = rng.integers(3)
    if kind == 0:  # another dtype in the header (its length kept or not)
        data = data.replace(b"'<f4'", DTYPES[int(rng.integers(len(DTYPES)))], 1)
    elif kind == 1:  # another shape
        shape = [b"(64, 6)", b"(6, 64)", b"(64,)", b"(0, 6)", b"(99999999999, 6)", b"(-1, 6)",
                 b"(64, 6, 1)", b"()", b"(2**70, 6)"][int(rng.integers(9))]  # fmt: skip
        data = data.replace(b"(64, 6)", shape, 1)
    else:
        path.write_bytes(data)
        mutate_bytes(path, rng)
        return
    path.write_bytes(data)


@pytest.fixture(scope="module")
def eval_material(tmp_path_factory) -> Path:
    return container.write_container(tmp_path_factory.mktemp("fuzz") / "l.btfm", LambertianBTF(0.5))


def _query_estimate(path: Path) -> int:
    rows = max(path.stat().st_size // 24, 1)  # at most this many float32 rows fit the file
    return memory.queries(rows, "").peak_bytes


READERS: list[Reader] = [
    Reader(
        "btfbase-text",
        btfbase_seed,
        btfbase_mutate,
        lambda p, out: ["info", str(p)],
        lambda p: memory.btf_load(p).peak_bytes,
        count=24,
    ),
    Reader(
        "btfbase-binary",
        btfbase_binary_seed,
        btfbase_binary_mutate,
        lambda p, out: ["info", str(p)],
        lambda p: memory.btf_load(p).peak_bytes,
        count=24,
    ),
    Reader(
        "ubo2014-dfmf",
        ubo2014_seed,
        mutate_bytes,
        lambda p, out: ["info", str(p)],
        lambda p: memory.btf_load(p).peak_bytes,
        count=40,
    ),
    *(
        Reader(
            f"btfm-{codec}",
            btfm_seed(codec),
            btfm_mutate,
            lambda p, out: ["convert", str(p), str(out / "copy.btfm")],
            lambda p: memory.btf_load(p).peak_bytes * 2,  # read, then written (a table copy)
            count=25,
        )
        for codec in BTFM_SEEDS
    ),
    Reader(
        "exr-environment",
        exr_seed,
        mutate_bytes,
        lambda p, out: ["envmap", str(p), "--lights", "64", "-o", str(out / "l.npz")],
        lambda p: (
            memory.environment(32, 16, "").peak_bytes + memory.virtual_lights(64, "").peak_bytes
        ),
        count=60,
    ),
    Reader(
        "npy-queries",
        npy_seed,
        npy_mutate,
        None,  # set below: needs the material fixture
        _query_estimate,
        count=60,
    ),
]


class HangError(Exception):
    pass


def _alarm(_signum, _frame):
    raise HangError(f"a case took longer than {HANG_SECONDS} s")


@pytest.mark.parametrize("reader", READERS, ids=[r.name for r in READERS])
def test_reader_survives_fuzzing(reader, tmp_path, capsys, eval_material):
    argv = reader.argv or (
        lambda p, out: [
            "eval",
            str(eval_material),
            "--queries",
            str(p),
            "--out",
            str(out / "v.npy"),
        ]
    )
    rng = np.random.default_rng(18)
    pristine = tmp_path / "pristine"
    pristine.mkdir()
    seed = reader.seed(pristine)
    outcomes = {0: 0, 2: 0}
    previous = signal.signal(signal.SIGALRM, _alarm)
    try:
        for case in range(reader.count * SCALE):
            work = tmp_path / f"case{case}"
            work.mkdir()
            target = work / seed.name
            (shutil.copytree if seed.is_dir() else shutil.copy)(seed, target)
            reader.mutate(target, rng)
            estimate = reader.estimate(target)
            tracemalloc.start()
            signal.alarm(HANG_SECONDS)
            try:
                code = main(["-v", *argv(target, work)])
            finally:
                signal.alarm(0)
                _current, peak = tracemalloc.get_traced_memory()
                tracemalloc.stop()
            err = capsys.readouterr().err
            assert code in (0, 2), f"{reader.name} case {case}: exit {code}: {err}"
            assert code == 0 or err.strip(), f"{reader.name} case {case}: refused silently"
            assert peak <= estimate + SLACK_BYTES, (
                f"{reader.name} case {case}: {peak} bytes traced, estimate {estimate}"
            )
            outcomes[code] += 1
            shutil.rmtree(work)
    finally:
        signal.signal(signal.SIGALRM, previous)
    assert outcomes[2] > 0  # the mutations do damage: some inputs must have been refused

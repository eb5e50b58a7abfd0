"""Restoring the maxima that BTFbase's ``binary.btf`` wrapped to 0 (docs/formats.md).

The original tool quantises a float table to bytes as ``q = (v − min)·256/(max − min)``, so the
entries equal to the table's maximum get ``q = 256``, which wraps to 0 in a byte: they read back
as the minimum. The byte 0 is therefore ambiguous — the true minimum (there is at least one) or a
wrapped maximum (there is at least one: the stored max is some entry's value). Each such
*candidate* is decided by the first rule that settles it:

1. **Row sums** (P1 only, ``exact``): P1 rows are luminance curves normalised to sum 1. With the
   row's candidates at the minimum the sum is S₀; each wrapped maximum adds ``max − min``. The one
   count k with ``|S₀ + k·(max − min) − 1| ≤ n·step/2`` (the quantisation's bound) is the number
   of maxima in the row; k = 0 or k = all settles every candidate of the row. The rule is used only
   when every row without candidates sums to 1 within that bound.
2. **Jumps** (``inferred``): along the table's ordered axis (P1 over β, P2 scale over α, P3 scale
   over θv, P4 scale over φv with wrap, P6 scale over the texture with wrap; a colour's
   neighbours are the colours IndexAB's runs over β interpolate it with, per channel) each entry
   is compared with the mean of its neighbours. If one reading of a candidate would be a larger jump
   than any other entry of the table makes and the other reading would not, the other reading is
   taken (repeated, so a run of candidates is settled from its ends inwards). The readings must
   leave at least one minimum and one maximum among the candidates, else this rule's decisions
   are dropped (a table whose extremes are isolated spikes, like the P4 scales, defeats it).
3. **Counting** (``inferred``): when one candidate is left and no maximum (or no minimum) has
   been found, it is that one.

What no rule settles is **ambiguous** and is set to the midpoint ``(min + max)/2`` — the value of
least expected squared error when either reading is as likely — and reported.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # btfbase_binary imports this module
    from .btfbase_binary import QuantisedTable

#: How each float table's neighbours are found: (axis kind, wraps). "row": along axis 1.
ORDER = {
    "pdf1": ("row", False),
    "pdf2_scale": ("row", False),
    "pdf3_scale": ("row", False),
    "pdf4_scale": ("row", True),
    "pdf6_scale": ("grid", True),
    "ab_colors": ("runs", False),  # colours next to each other in IndexAB's runs over β
}

#: Largest number of candidates in one P1 row the row-sum rule considers.
MAX_ROW_CANDIDATES = 16

UNDECIDED, LOW, HIGH = -1, 0, 1


@dataclass(frozen=True)
class TableRecovery:
    """What happened to one float table's byte-0 entries."""

    table: str
    candidates: int  # entries stored as byte 0: the minimum or a wrapped maximum
    exact: int  # settled by an identity the table satisfies (P1 row sums)
    inferred: int  # settled by the jump or counting rules
    ambiguous: int  # not settled: set to the midpoint
    maxima: int  # candidates restored to the maximum (exact or inferred)
    max_error: float  # the largest error an ambiguous entry can carry: (max − min)/2

    @property
    def recovered(self) -> bool:
        """Every value is the original's (to the quantisation step)."""
        return self.ambiguous == 0

    def describe(self) -> str:
        text = (
            f"{self.table}: {self.candidates} entries stored as byte 0 (the minimum or a wrapped "
            f"maximum), {self.exact + self.inferred} settled ({self.exact} by row sums, "
            f"{self.inferred} by neighbours or counting), {self.maxima} restored to the maximum"
        )
        if self.ambiguous:
            text += (
                f"; {self.ambiguous} ambiguous, set to the midpoint of the table's range: off "
                f"by up to {self.max_error:.6g}"
            )
        return text

    def to_json(self) -> dict:
        return {
            "candidates": self.candidates,
            "maxima": self.maxima,
            "exact": self.exact,
            "inferred": self.inferred,
            "ambiguous": self.ambiguous,
            "max_error": self.max_error,
        }


def recover_table(
    name: str, table: QuantisedTable, index_ab: np.ndarray | None = None
) -> tuple[np.ndarray, TableRecovery]:
    """(rows, cols) float32 values of a stored float table with its wrapped maxima restored
    where the rules allow, and the account of it. ``index_ab`` (the IndexAB table) gives the
    colour table its neighbours: the colours a run interpolates between."""
    values = table.values()
    codes = table.codes
    cand = codes == 0
    n_cand = int(cand.sum())
    gap = float(table.high) - float(table.low)
    if gap <= 0.0 or n_cand == 0:  # a constant table: nothing wrapped
        return values, TableRecovery(name, n_cand, 0, 0, 0, 0, 0.0)
    low = values.astype(np.float64)  # every candidate read as the minimum
    state = np.full(codes.shape, UNDECIDED, dtype=np.int8)
    exact = np.zeros(codes.shape, dtype=bool)
    if name == "pdf1":
        _row_sums(low, cand, gap, table.step, state)
        exact = cand & (state != UNDECIDED)
    kind, wraps = ORDER.get(name, (None, False))
    runs = None
    if kind == "runs" and index_ab is not None:
        runs = _run_neighbours(index_ab, len(codes))
    if kind in ("row", "grid") or runs is not None:
        _jumps(low, cand, gap, state, kind, wraps, runs)
    _counting(cand, state)
    ambiguous = cand & (state == UNDECIDED)
    out = values.copy()
    out[cand & (state == HIGH)] = np.float32(table.high)
    out[ambiguous] = np.float32((float(table.low) + float(table.high)) / 2.0)
    n_exact = int(exact.sum())
    n_amb = int(ambiguous.sum())
    return out, TableRecovery(
        table=name,
        candidates=n_cand,
        exact=n_exact,
        inferred=n_cand - n_exact - n_amb,
        ambiguous=n_amb,
        maxima=int((cand & (state == HIGH)).sum()),
        max_error=gap / 2.0 if n_amb else 0.0,
    )


def _row_sums(low: np.ndarray, cand: np.ndarray, gap: float, step: float, state) -> None:
    """P1 rule: each row sums to 1 within n·step/2 (module docstring, rule 1)."""
    tol = low.shape[1] * step / 2.0 + 1e-6
    sums = low.sum(axis=1)
    per_row = cand.sum(axis=1)
    clean = per_row == 0
    if not clean.any() or np.abs(sums[clean] - 1.0).max() > tol:
        return  # the table is not normalised as P1 should be: the rule does not apply
    for r in np.flatnonzero((per_row > 0) & (per_row <= MAX_ROW_CANDIDATES)):
        counts = [k for k in range(per_row[r] + 1) if abs(sums[r] + k * gap - 1.0) <= tol]
        if counts == [0]:
            state[r, cand[r]] = LOW
        elif counts == [per_row[r]]:
            state[r, cand[r]] = HIGH


def _run_neighbours(index_ab: np.ndarray, n_colours: int) -> np.ndarray | None:
    """(colours, colours) counts of how often two different colours are neighbours in an
    IndexAB run over β (the decoder interpolates between them), or None if indices are out
    of range (the MLVQ validation reports that)."""
    if index_ab.size == 0 or index_ab.min() < 0 or index_ab.max() >= n_colours:
        return None
    a, b = index_ab[:, :-1].ravel(), index_ab[:, 1:].ravel()
    apart = a != b
    counts = np.zeros((n_colours, n_colours))
    np.add.at(counts, (a[apart], b[apart]), 1.0)
    return counts + counts.T


def _neighbour_mean(
    a: np.ndarray, usable: np.ndarray, kind: str, wraps: bool, runs: np.ndarray | None = None
) -> np.ndarray:
    """Mean of each entry's usable neighbours along the table's order (NaN where none)."""
    if kind == "runs":  # per channel, over the colours each colour's runs lead to
        total = runs @ np.where(usable, a, 0.0)
        count = runs @ usable.astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(count > 0, total / np.maximum(count, 1e-300), np.nan)
    total = np.zeros_like(a)
    count = np.zeros_like(a)
    axes = (1,) if kind == "row" else (0, 1)
    for axis in axes:
        n = a.shape[axis]
        for shift in (-1, 1):
            idx = np.arange(n) + shift
            inside = np.ones(n, dtype=bool) if wraps else (idx >= 0) & (idx < n)
            idx = idx % n
            v = np.take(a, idx, axis=axis)
            ok = np.take(usable, idx, axis=axis)
            shape = [1, 1]
            shape[axis] = n
            ok = ok & inside.reshape(shape)
            total += np.where(ok, v, 0.0)
            count += ok
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def _jumps(low, cand, gap, state, kind: str, wraps: bool, runs=None) -> None:
    """Jump rule (module docstring, rule 2), on the candidates still undecided; repeated while
    it settles more (a run of byte-0 entries is settled from its ends inwards)."""
    usable = ~cand
    pred = _neighbour_mean(low, usable, kind, wraps, runs)
    residual = np.abs(low - pred)[~cand & np.isfinite(pred)]
    if residual.size == 0:
        return
    largest = float(residual.max())  # the largest jump any other entry makes
    decided = state.copy()
    while True:
        a = np.where(cand & (decided == HIGH), low + gap, low)
        pred = _neighbour_mean(a, ~cand | (decided != UNDECIDED), kind, wraps, runs)
        todo = cand & (decided == UNDECIDED) & np.isfinite(pred)
        as_low = np.abs(low - pred)
        as_high = np.abs(low + gap - pred)
        to_low = todo & (as_high > largest) & (as_low <= largest)
        to_high = todo & (as_low > largest) & (as_high <= largest)
        if not (to_low.any() or to_high.any()):
            break
        decided[to_low] = LOW
        decided[to_high] = HIGH
    left = cand & (decided == UNDECIDED)
    has_low = (cand & (decided == LOW)).any() or left.any()
    has_high = (cand & (decided == HIGH)).any() or left.any()
    if has_low and has_high:  # else the readings contradict the stored range: drop them
        state[...] = decided


def _counting(cand: np.ndarray, state: np.ndarray) -> None:
    """Counting rule (module docstring, rule 3)."""
    left = cand & (state == UNDECIDED)
    if left.sum() != 1:
        return
    if not (cand & (state == HIGH)).any():
        state[left] = HIGH
    elif not (cand & (state == LOW)).any():
        state[left] = LOW

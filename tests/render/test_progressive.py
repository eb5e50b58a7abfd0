"""Progressive lighting state (render/progressive.py): batches of K lights until N are in."""

from __future__ import annotations

import pytest

from btf_addon.render.progressive import ProgressiveState


def test_progressive_state_batches_and_restarts():
    s = ProgressiveState(total=10, per_pass=4)
    batches = []
    while not s.converged:
        first, count = s.next_batch()
        batches.append((first, count))
        s.advance(count)
    assert batches == [(0, 4), (4, 4), (8, 2)]
    assert s.next_batch() == (10, 0)
    gen = s.generation
    s.restart()
    assert s.done == 0 and s.generation == gen + 1
    with pytest.raises(ValueError):
        ProgressiveState(total=0, per_pass=1)

"""Progressive lighting state: which virtual lights are already accumulated in the image.

The viewport adds K lights per redraw until all N are in; any change to what is drawn (view,
objects, materials, World, settings) restarts from zero. Because every prefix of the light list
is a stratified estimate (core/sampling/envmap.py), the image after k lights is already a fair
result:
the resolve divides the accumulated sum by k. Each view holds its own state (gl/drawer.py
``ViewAccumulation``): two eyes over one scene progress independently.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class ProgressiveState:
    total: int  # N
    per_pass: int  # K
    done: int = 0
    generation: int = 0  # bumps on every restart: tells a caller its image was started over

    def __post_init__(self) -> None:
        if self.total < 1 or self.per_pass < 1:
            raise ValueError("need at least one light in total and per pass")

    def restart(self) -> None:
        self.done = 0
        self.generation += 1

    @property
    def converged(self) -> bool:
        return self.done >= self.total

    def next_batch(self) -> tuple[int, int]:
        """(first, count) of the lights to add now; count 0 once converged."""
        count = min(self.per_pass, self.total - self.done)
        return self.done, max(count, 0)

    def advance(self, count: int) -> None:
        self.done = min(self.total, self.done + count)

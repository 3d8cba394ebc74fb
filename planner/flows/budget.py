"""The planner's wall-clock budget: when it started, how much is left, when to stop.

`seconds=None` means no time budget: nothing ever expires and the plan depends on the
seed and the iteration budget alone. A `reserve` is kept back for the work that follows
the searches (the final exact check and building the plan), so that the planner returns
close to its budget rather than past it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

CLOCK: Callable[[], float] = time.perf_counter
"""The clock every budget reads. Tests set it to process time (`time.process_time`), so
that a budget's promise is measured in the planner's own work, not in the wall time a
loaded machine gives it."""


def now() -> float:
    return CLOCK()


StopReason = Literal["converged", "budget", "iterations"]
"""Why planning stopped: nothing left to improve, the time budget, the iteration budget."""


@dataclass
class Budget:
    seconds: float | None
    started: float = field(default_factory=now)
    reserve: float = 0.0

    def __post_init__(self) -> None:
        if self.seconds is not None and not self.seconds > 0:
            raise ValueError(f"a time budget must be positive seconds or None, got {self.seconds}")

    def elapsed(self) -> float:
        return now() - self.started

    def remaining(self) -> float:
        """Seconds left before the searches must stop (inf without a time budget)."""
        if self.seconds is None:
            return float("inf")
        return self.seconds - self.reserve - self.elapsed()

    def expired(self) -> bool:
        return self.remaining() <= 0.0

    def percent(self) -> float | None:
        """Share of the time budget used so far, in percent (None without one)."""
        if self.seconds is None:
            return None
        return min(100.0, 100.0 * self.elapsed() / self.seconds)

    def keep_back(self, seconds: float) -> None:
        """Reserve at least `seconds` (but never more than a quarter of the budget) for
        the work after the searches."""
        if self.seconds is not None:
            self.reserve = max(self.reserve, min(seconds, self.seconds / 4))

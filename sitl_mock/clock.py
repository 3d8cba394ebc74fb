"""Simulated time: fixed physics steps, with the loop's clock deciding only how many to run.

The loop's clock is real time in production and virtual on a `VirtualTimeLoop`, where
the simulation and the ground station share it and a flight replays exactly. Like
ArduPilot's SITL, the simulation never runs ahead of what the machine can do: each tick
runs at most a few steps before the event loop handles the links again, and time that
could not be run is let go (the simulation slips: it runs slower than its speed-up)
rather than caught up in one burst. A ground station therefore always has its answers
taken in within a tenth of a simulated second, loaded machine or not, as it would with a
real autopilot, instead of the vehicles flying seconds on without hearing it.
"""

from __future__ import annotations

import asyncio
import time

DEFAULT_STEP_S = 0.02
STEP_EPSILON = 1e-6
"""Of a step: a wake-up at a step's due time counts that step, float rounding or not."""
MAX_STEPS_PER_TICK = 5
"""Steps run before the links are served again (0.1 simulated s): beyond that, slip."""


def loop_time() -> float:
    """The running event loop's clock, the one clock of a simulation (virtual on a
    `VirtualTimeLoop`); the monotonic clock when no loop runs (stepping by hand)."""
    try:
        return asyncio.get_running_loop().time()
    except RuntimeError:
        return time.monotonic()


class SimClock:
    """Counts fixed steps; `steps_due` maps elapsed wall time times the speed-up to whole steps."""

    def __init__(self, speedup: float, step_s: float = DEFAULT_STEP_S) -> None:
        if speedup <= 0:
            raise ValueError(f"speedup must be positive, got {speedup}")
        if step_s <= 0:
            raise ValueError(f"step must be positive, got {step_s}")
        self.speedup = speedup
        self.step_s = step_s
        self.steps = 0
        self._wall_start: float | None = None
        self._slipped_steps = 0

    @property
    def now(self) -> float:
        """Simulated seconds since start."""
        return self.steps * self.step_s

    def start(self, wall_now: float | None = None) -> None:
        self._wall_start = loop_time() if wall_now is None else wall_now
        self._slipped_steps = 0

    def steps_due(self, wall_now: float | None = None) -> int:
        """How many steps to run now to keep simulated time at speedup x wall time."""
        if self._wall_start is None:
            self.start(wall_now)
        wall = loop_time() if wall_now is None else wall_now
        start = self._wall_start if self._wall_start is not None else wall
        elapsed = (wall - start) * self.speedup / self.step_s
        target = int(elapsed + STEP_EPSILON) - self._slipped_steps
        due = max(0, target - self.steps)
        if due > MAX_STEPS_PER_TICK:
            self._slipped_steps += due - MAX_STEPS_PER_TICK
            due = MAX_STEPS_PER_TICK
        return due

    def wall_until_next_step(self, wall_now: float | None = None) -> float:
        """Real seconds until the next step falls due (0 if already due)."""
        if self._wall_start is None:
            return self.step_s / self.speedup
        wall = loop_time() if wall_now is None else wall_now
        due_at = (self.steps + 1 + self._slipped_steps) * self.step_s / self.speedup
        return max(0.0, self._wall_start + due_at - wall)

    def advance(self) -> float:
        self.steps += 1
        return self.now


class Deadline:
    """A point in simulated time that can be armed, cleared and tested."""

    def __init__(self) -> None:
        self.at: float | None = None

    def set(self, at: float) -> None:
        self.at = at

    def clear(self) -> None:
        self.at = None

    def passed(self, now: float) -> bool:
        return self.at is not None and now >= self.at

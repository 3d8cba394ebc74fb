"""When one optimizer run stops: at its iteration budget, on convergence, or at the deadline.

A run has converged when its best cost has not improved by more than `tolerance`
(relative) for `patience` iterations in a row. A run that only has to make a UAV safe
(`safe_below`: every cost below it is a safe path) converges sooner, after
`safe_patience` iterations without gain once its best is safe: the improvement phase
shortens the path later. Without patience a run does all of its iterations unless the
time budget ends it first.
"""

from __future__ import annotations

from dataclasses import dataclass

from planner.flows.budget import Budget, StopReason


@dataclass
class RunStop:
    budget: Budget
    patience: int | None
    tolerance: float = 1e-6
    safe_below: float | None = None
    safe_patience: int = 10
    reason: StopReason = "iterations"
    _best: float = float("inf")
    _since: int = 0

    def __call__(self, best_cost: float) -> bool:
        """Called with the best cost after every iteration; True stops the run."""
        if self._best == float("inf") or best_cost < self._best - self.tolerance * max(
            abs(self._best), 1.0
        ):
            self._best, self._since = best_cost, 0
        else:
            self._since += 1
        if self.budget.expired():
            self.reason = "budget"
            return True
        if self.patience is None:
            return False
        safe = self.safe_below is not None and self._best < self.safe_below
        if self._since >= (min(self.patience, self.safe_patience) if safe else self.patience):
            self.reason = "converged"
            return True
        return False

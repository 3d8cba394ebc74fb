"""Who is stopped, and by whom: the operator's holds and the schedule keeper's pauses.

Both stop a vehicle the same way (DO_PAUSE_CONTINUE in AUTO), but only the operator's
continue lifts an operator's hold: the schedule keeper pauses and resumes vehicles for
timing, and a vehicle the operator holds is never among those it resumes.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Holds:
    operator: set[str] = field(default_factory=set)  # held by the operator
    keeper: set[str] = field(default_factory=set)  # paused by the schedule keeper

    @property
    def stopped(self) -> set[str]:
        return self.operator | self.keeper

    def hold(self, uav_ids: set[str]) -> None:
        self.operator |= uav_ids

    def release(self, uav_ids: set[str]) -> set[str]:
        """Lift the operator's holds on `uav_ids`; the vehicles that may move again now."""
        self.operator -= uav_ids
        return uav_ids - self.keeper

    def keeper_pauses(self, uav_ids: frozenset[str]) -> set[str]:
        """The keeper's pauses; the vehicles that must be told to stop (not already)."""
        fresh = set(uav_ids) - self.stopped
        self.keeper |= uav_ids
        return fresh

    def keeper_resumes(self, uav_ids: frozenset[str]) -> set[str]:
        """The keeper lets go; the vehicles that may move again (not held by the operator)."""
        self.keeper -= uav_ids
        return set(uav_ids) - self.operator

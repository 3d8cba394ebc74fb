"""What one fuzzed flight is made of, drawn from its seed alone."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planner.cases import load_case
from planner.experiments.scenario_generator import (
    crossing_scenario,
    gap_swap_scenario,
    random_scenario,
)
from planner.model.scenario import Scenario
from sitl_mock import Faults

FAMILIES = ("crossing", "random", "gap-swap")
ORIGIN = load_case("case-6").origin
LATE_TAKE_OFF_S = 15.0
VEHICLE_ACTIONS = ("hold", "continue", "land", "rtl")
FLEET_ACTIONS = ("pause", "continue", "abort-land", "abort-rtl", "object", "restart")
LINK_DROPS_S = (2.0, 5.0, 10.0)
"""How long a vehicle's link is silent, both ways, in a flight with link drops."""


@dataclass(frozen=True)
class Action:
    """Something the operator does `at_s` seconds after asking the flight to start."""

    at_s: float
    kind: str
    uav: int | None = None  # the vehicle (sysid) of a per-vehicle action
    cell: tuple[int, int] | None = None  # where an object is reported
    seconds: float | None = None  # how long a link drop lasts ("silence")

    def describe(self) -> str:
        who = f" uav{self.uav}" if self.uav is not None else ""
        where = f" at {self.cell}" if self.cell is not None else ""
        lasting = f" for {self.seconds:g} s" if self.seconds is not None else ""
        return f"{self.kind}{who}{where}{lasting} at {self.at_s:.1f} s"


DEFAULT_MAX_UAVS = 6
"""The CI batch's flights: 2 to 6 UAVs (`--max-uavs` for more)."""


@dataclass(frozen=True)
class FuzzCase:
    seed: int
    family: str
    size: int
    uavs: int
    speed_m_s: float
    faults: dict[int, Faults] = field(default_factory=dict)  # by sysid
    late: int | None = None  # the sysid that takes off LATE_TAKE_OFF_S late
    actions: tuple[Action, ...] = ()
    storage_delay_s: float = 0.002
    resume: bool = False  # after a restart, the operator resumes the flight (else aborts)
    max_uavs: int = DEFAULT_MAX_UAVS  # the bound it was drawn with (to replay it)

    @classmethod
    def draw(
        cls, seed: int, max_uavs: int = DEFAULT_MAX_UAVS, link_drops: bool = False
    ) -> FuzzCase:
        """The seed's flight; `link_drops`: with one vehicle's link silent for a while
        (drawn on a stream of its own: the rest of the flight is the seed's as without)."""
        rng = np.random.default_rng([seed, 0xF1])
        family = FAMILIES[int(rng.integers(len(FAMILIES)))]
        uavs = int(rng.integers(1, max_uavs // 2 + 1)) * 2  # even: gap swaps need pairs
        size = int(rng.integers(8, 12))
        while family == "gap-swap" and not _gap_swap_fits(size, uavs):
            size += 1  # only from 10 UAVs (--max-uavs 12): the seeds below draw as before
        faults = {sysid: _faults(rng) for sysid in range(1, uavs + 1) if rng.random() < 0.5}
        late = int(rng.integers(1, uavs + 1)) if rng.random() < 0.2 else None
        actions = tuple(
            sorted((_action(rng, uavs, size) for _ in range(int(rng.integers(0, 4)))),
                   key=lambda a: a.at_s)
        )  # fmt: skip
        resume = bool(np.random.default_rng([seed, 0xF2]).random() < 0.5)  # its own stream:
        # the seeds drawn before it still draw the same flights
        if link_drops:
            actions = tuple(sorted((*actions, _link_drop(seed, uavs)), key=lambda a: a.at_s))
        return cls(
            seed, family, size, uavs, float(rng.choice([5.0, 10.0])), faults, late, actions,
            float(rng.choice([0.0, 0.002, 0.02])), resume, max_uavs,
        )  # fmt: skip

    def scenario(self) -> Scenario:
        if self.family == "crossing":
            drawn = crossing_scenario(self.seed, size=self.size, uavs=self.uavs, objects=0)
        elif self.family == "random":
            drawn = random_scenario(self.seed, size=self.size, uavs=self.uavs, objects=0)
        else:
            drawn = gap_swap_scenario(self.seed, size=self.size, uavs=self.uavs)
        return drawn.model_copy(update={"origin": ORIGIN})

    def describe(self) -> str:
        faults = ", ".join(f"uav{k}: {_faults_text(f)}" for k, f in sorted(self.faults.items()))
        late = f"; uav{self.late} takes off {LATE_TAKE_OFF_S:.0f} s late" if self.late else ""
        actions = "; ".join(a.describe() for a in self.actions) or "none"
        if any(a.kind == "restart" for a in self.actions):
            actions += "; after the restart, " + ("resume" if self.resume else "abort")
        return (
            f"seed {self.seed}: {self.family} of {self.uavs} UAVs on {self.size}x{self.size} "
            f"cells at {self.speed_m_s:g} m/s; faults: {faults or 'none'}{late}; "
            f"storage {self.storage_delay_s * 1000:g} ms; operator: {actions}"
        )


def _faults(rng: np.random.Generator) -> Faults:
    return Faults(
        loss_in=float(rng.choice([0.0, 0.05, 0.2])),
        loss_out=float(rng.choice([0.0, 0.05, 0.2])),
        latency_s=float(rng.choice([0.0, 0.02, 0.1])),
        jitter_s=float(rng.choice([0.0, 0.02])),
        duplicate=float(rng.choice([0.0, 0.05])),
        reorder=float(rng.choice([0.0, 0.05])),
    )


def _faults_text(faults: Faults) -> str:
    named = {
        "loss in": faults.loss_in, "loss out": faults.loss_out, "latency": faults.latency_s,
        "jitter": faults.jitter_s, "dup": faults.duplicate, "reorder": faults.reorder,
    }  # fmt: skip
    return " ".join(f"{k} {v:g}" for k, v in named.items() if v) or "clean"


def _action(rng: np.random.Generator, uavs: int, size: int) -> Action:
    at = float(rng.uniform(0.0, 40.0))
    if rng.random() < 0.5:
        kind = VEHICLE_ACTIONS[int(rng.integers(len(VEHICLE_ACTIONS)))]
        return Action(at, kind, uav=int(rng.integers(1, uavs + 1)))
    kind = FLEET_ACTIONS[int(rng.integers(len(FLEET_ACTIONS)))]
    cell = (int(rng.integers(size)), int(rng.integers(size))) if kind == "object" else None
    return Action(at, kind, cell=cell)


def _link_drop(seed: int, uavs: int) -> Action:
    rng = np.random.default_rng([seed, 0xF3])
    at, uav = float(rng.uniform(3.0, 40.0)), int(rng.integers(1, uavs + 1))
    return Action(at, "silence", uav=uav, seconds=float(rng.choice(LINK_DROPS_S)))


def _gap_swap_fits(size: int, uavs: int) -> bool:
    """Whether `gap_swap_scenario` has room for `uavs` on each side of its wall."""
    wall = size // 2
    return 2 * uavs <= size * min(wall - 1, size - wall - 2)

"""Where a flight's time goes: the plan's own clock, copters flying alone, and the
passing order kept with and without what keeping it costs.

`bench/flight_speed.py` measures flights against the product's own timed flight
(`FlightPlan.duration_s`). This one takes that timing apart, on the ground station's own
model of the vehicles (`gcs.mission.flight_timing`, the one the product times flights
and judges their safety with), with the plans `flight_speed.py` flies:

- *plan*: the plan's clock stretched to the flight speed (instant speed changes, a UAV
  gone the moment it reaches its goal);
- *alone*: every vehicle flying its path with its limits, nobody waiting for anybody
  (jerk-limited S-curves, corners, the stop at the end);
- *order, no landing*: the passing order kept as the product keeps it (stopping
  distances, the reaction time), but a UAV out of the way the moment it reaches its
  goal, as the plan has it;
- *order, 2R down*: the same, with a UAV out of the way once its landing has taken it
  2R below the others (what counting vertical separation would give; the product does
  not: its separation is the plan's, in the plane);
- *product*: the product's timing, a vehicle in the way until it has landed at its goal;
- *soonest of 8*: the same, for the soonest of eight candidate plans at that speed
  (`mvo-gcs fly --candidates 8`, `gcs.mission.flight_choice`: seeds 1 to 8, clearance
  1.3 m and 0.5 m wider each): the planner's clock does not rank plans as copters fly
  them.

- *instant, order*: the passing order kept by copters that change speed within a fraction
  of a second (`INSTANT`; no reaction time or buffer either), a UAV out of the way the
  moment it reaches its goal: against *plan*, what keeping the order itself costs;
  against *order, no landing*, what stopping and starting copters for it costs (not one
  of the bounds below: it can be sooner than *alone*).

Each column up to *product* is a lower bound on the ones after it. Run:

    .venv/bin/python bench/flight_time.py
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gcs.cli.planning_options import add_planning_arguments, planner_settings  # noqa: E402
from gcs.mavlink.mission_item import Autopilot  # noqa: E402
from gcs.mission.flight_choice import candidate, soonest  # noqa: E402
from gcs.mission.flight_plan import DEFAULT_CLEARANCE_M, FlightPlan, flight_plan  # noqa: E402
from gcs.mission.flight_timing import fly  # noqa: E402
from gcs.mission.motion import LAND_SETTLE_S, CopterLimits, StoppingRule  # noqa: E402
from planner.experiments.machine import describe_machine  # noqa: E402
from planner.model.plan import Plan  # noqa: E402
from planner.model.scenario import Scenario  # noqa: E402
from planner.pipeline import plan  # noqa: E402

sys.path.insert(0, str(ROOT / "bench"))
from flight_speed import PLANNING, scenarios  # noqa: E402

RESULTS = ROOT / "bench" / "results" / "flight_time.md"
SPEEDS = (1.0, 5.0, 10.0)
CANDIDATES = 8
COLUMNS = (
    "plan", "alone", "order, no landing", "order, 2R down", "product", f"soonest of {CANDIDATES}",
    "instant, order",
)  # fmt: skip
INSTANT = {
    "accel_m_s2": 10.0,
    "jerk_m_s3": 50.0,
    "stop_jerk_m_s3": 50.0,
    "corner_accel_m_s2": 20.0,
}
"""Limits of a copter that changes speed within a fraction of a second (10 m/s in about
1.2 s from rest): quicker ones the timing's 0.05 s steps do not follow."""


@dataclass
class Row:
    scenario: str
    uavs: int
    speed: float
    seconds: dict[str, float]


@dataclass(frozen=True)
class OutOfTheWayBelow(CopterLimits):
    """A lander taken for out of the way once it is `drop_m` below where it stopped:
    LAND settles, then comes down at WPNAV_SPEED_DN (`CopterLimits.landing_time`) until
    LAND_ALT_LOW; a drop that reaches below that counts the whole landing."""

    drop_m: float = 0.0

    def landing_time(self, altitude_m: float) -> float:
        if altitude_m - self.drop_m < self.land_slow_below_m:
            return super().landing_time(altitude_m)
        speed_up_s = self.descent_m_s / (2 * self.vertical_accel_m_s2)  # (lost to it)
        return LAND_SETTLE_S + speed_up_s + self.drop_m / self.descent_m_s


def last_arrival(
    flight: FlightPlan,
    altitude_m: float,
    limits: dict[str, CopterLimits] | None = None,
    rule: StoppingRule | None = None,
) -> float:
    """The passing order kept, landings from `altitude_m` (0: no landing)."""
    timed = fly(
        flight.paths, flight.leg_speeds, limits or flight.limits, flight.order, rule,
        altitude_m=altitude_m, stops=flight.stops,
    )  # fmt: skip
    return max(t.arrival_s for t in timed.values())


def two_r_down(flight: FlightPlan) -> dict[str, CopterLimits]:
    """Each vehicle's limits, its landing out of the way 2R down (its own and the widest
    other's radius, as the plan keeps them apart)."""
    widest = max(p.radius_m for p in flight.paths.values())
    return {
        uav: OutOfTheWayBelow(
            **dataclasses.asdict(limits), drop_m=flight.paths[uav].radius_m + widest
        )
        for uav, limits in flight.limits.items()
    }


AT_ONCE = StoppingRule(reaction_s=0.0, buffer_m=0.0, creep_buffer_m=0.0)
"""The stopping rule with nothing between seeing and stopping."""


def instant(flight: FlightPlan) -> dict[str, CopterLimits]:
    return {uav: dataclasses.replace(lim, **INSTANT) for uav, lim in flight.limits.items()}


def measure(name: str, scenario: Scenario, speeds: tuple[float, ...]) -> list[Row]:
    parser = argparse.ArgumentParser()
    add_planning_arguments(parser)
    settings = planner_settings(parser.parse_args([name, *PLANNING]))
    plans = [
        plan(candidate(scenario, DEFAULT_CLEARANCE_M, k), settings.candidate(k, CANDIDATES))
        for k in range(CANDIDATES)
    ]
    planned = plans[0]  # the plan flight_speed.py flies
    autopilots = {u.id: Autopilot.ARDUPILOT for u in scenario.uavs}
    rows = []
    for speed in speeds:

        def at_speed(candidate: Plan, speed: float = speed) -> FlightPlan:
            return flight_plan(candidate, scenario, autopilots, max_speed_m_s=speed)

        flight = at_speed(planned)
        alone = fly(flight.paths, flight.leg_speeds, flight.limits, None, stops=flight.stops)
        seconds = {
            "plan": max(float(p.arrive[-1]) for p in flight.paths.values()),
            "alone": max(t.arrival_s for t in alone.values()),
            "order, no landing": last_arrival(flight, 0.0),
            "order, 2R down": last_arrival(flight, flight.altitude_m, two_r_down(flight)),
            "product": flight.duration_s,
            COLUMNS[-2]: soonest(plans, at_speed).flight.duration_s,
            COLUMNS[-1]: last_arrival(flight, 0.0, instant(flight), AT_ONCE),
        }
        rows.append(Row(name, len(scenario.uavs), speed, seconds))
    return rows


def write(rows: list[Row], out: Path, began: datetime, wall_s: float) -> None:
    head = "| scenario | UAVs | m/s | " + " | ".join(f"{c} s" for c in COLUMNS) + " |"
    lines = [
        "# Where a flight's time goes",
        "",
        f"Run {began:%Y-%m-%d %H:%M} UTC on {describe_machine()}, {wall_s:.0f} s.",
        "",
        "```",
        ".venv/bin/python bench/flight_time.py",
        "```",
        "",
        "The last arrival over a goal, seconds from the common start, on the ground "
        "station's model of the vehicles (`gcs.mission.flight_timing`), for the plans "
        "`bench/flight_speed.py` flies (see `bench/flight_time.py` for each column). "
        "*product* is the timing `mvo-gcs fly` prints, which flights are measured against.",
        "",
        head,
        "| --- | ---: | ---: |" + " ---: |" * len(COLUMNS),
    ]
    for row in rows:
        cells = " | ".join(f"{row.seconds[c]:.1f}" for c in COLUMNS)
        lines.append(f"| {row.scenario} | {row.uavs} | {row.speed:g} | {cells} |")
    out.write_text("\n".join(lines) + "\n")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generated", type=int, default=1, help="seeds per family")
    parser.add_argument("--speeds", default=",".join(f"{s:g}" for s in SPEEDS))
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args()
    speeds = tuple(float(s) for s in args.speeds.split(","))
    began, clock = datetime.now(UTC), time.perf_counter()
    rows = []
    for name, scenario in scenarios(args.generated):
        rows.extend(measure(name, scenario, speeds))
        print(rows[-1], flush=True)
    write(rows, args.out, began, time.perf_counter() - clock)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

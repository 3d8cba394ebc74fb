"""`mvo-gcs fly`: plan a scenario, upload the missions, fly them together and follow.

UAV k of the scenario flies on the k-th connection of `--vehicles`. The plan is flown
with its fastest UAV at `--max-speed` (5 m/s by default), keeping its passing order
(`gcs.mission.flight_plan`); a speed the ground station cannot keep safe is refused
before anything is armed, naming the highest one it can. At the end the separation
actually flown, from the vehicles' reported positions, is printed against the plan's
2R. Scenario, plan and speed errors exit 2, a vehicle failure or a flown separation
under 2R exits 1. `--dry-run` stops before the upload: the speed checked against the
vehicles' own limits and the flight's timing printed, nothing uploaded or armed (a faster
cruise is not always sooner, so a few speeds can be compared first). With
`--candidates N` the scenario is planned N times (the next seed and a wider clearance
each time) and the plan the vehicles fly soonest at that speed is flown
(`gcs.mission.flight_choice`).
"""

from __future__ import annotations

import argparse
import asyncio
import sys

from gcs.cli.planning_options import (
    ScenarioFileError,
    add_planning_arguments,
    planner_settings,
    positive_int,
    read_scenario,
)
from gcs.cli.progress_display import ProgressDisplay
from gcs.fleet.fleet import Fallback, Fleet, FleetSettings, FlightReport
from gcs.fleet.vehicle_limits import read_limits
from gcs.mavlink import client
from gcs.mavlink.errors import GcsError
from gcs.mavlink.link import VehicleLink
from gcs.mission.build import DEFAULT_ALTITUDE_M
from gcs.mission.flight_choice import WIDER_M, Choice, candidate, soonest
from gcs.mission.flight_plan import (
    DEFAULT_CLEARANCE_M,
    TURN_RADIUS_M,
    FlightPlan,
    UnsafeSpeed,
    flight_plan,
)
from gcs.mission.flight_timing import FlightStuck
from gcs.mission.motion import DEFAULT_SPEED_M_S
from planner.model.plan import Plan
from planner.model.scenario import Scenario


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_planning_arguments(parser)
    parser.add_argument(
        "--vehicles",
        required=True,
        help="comma-separated connection strings, one per UAV in scenario order "
        "(udpout:HOST:PORT, udpin:HOST:PORT, tcp:HOST:PORT)",
    )
    parser.add_argument(
        "--altitude",
        type=float,
        default=DEFAULT_ALTITUDE_M,
        help="metres above home (default: %(default)s)",
    )
    parser.add_argument(
        "--max-speed",
        type=float,
        default=DEFAULT_SPEED_M_S,
        help="the cruise speed of the plan's fastest UAV, m/s (default: %(default)s); "
        "refused, naming the highest safe one, if the flight cannot be kept safe at it",
    )
    parser.add_argument(
        "--turn-radius",
        type=float,
        default=TURN_RADIUS_M,
        help="waypoint acceptance radius, m: how much a turn may cut its "
        "corner (default: %(default)s)",
    )
    parser.add_argument("--finish", choices=["land", "rtl"], default="land")
    parser.add_argument(
        "--on-failure",
        choices=[f.value for f in Fallback],
        default="land",
        help="what the other vehicles do if one fails (default: %(default)s)",
    )
    parser.add_argument(
        "--clearance",
        type=float,
        default=DEFAULT_CLEARANCE_M,
        help="metres beyond 2R the plan keeps between UAVs, room to stray in flight "
        "(default: %(default)s)",
    )
    parser.add_argument(
        "--candidates",
        type=positive_int,
        default=1,
        metavar="N",
        help="plan N candidates, sharing --time-budget (the k-th from 0: seed --seed + k, "
        f"clearance --clearance + {WIDER_M:g} k m), and fly the one the vehicles reach "
        "their goals soonest with, timed at --max-speed (default: %(default)s)",
    )
    parser.add_argument(
        "--link-loss-brake",
        type=float,
        default=FleetSettings.link_loss_brake_s,
        metavar="S",
        help="a vehicle that has not heard us for S seconds brakes (ArduCopter's GCS "
        "failsafe, set at upload); 0 leaves its own failsafe settings (default: %(default)s)",
    )
    parser.add_argument("--connect-timeout", type=float, default=15.0)
    parser.add_argument(
        "--dry-run",
        action="store_true",
        help="check the speed with the vehicles' own limits and print the flight's timing "
        "(each UAV's arrival, whom it lets pass first); upload and arm nothing",
    )


def run(args: argparse.Namespace) -> int:
    scenario = read_scenario(args.scenario)
    urls = [u.strip() for u in args.vehicles.split(",") if u.strip()]
    if len(urls) != len(scenario.uavs):
        raise ScenarioFileError(
            f"{len(scenario.uavs)} UAVs in {scenario.name} but {len(urls)} vehicles given"
        )
    if scenario.origin is None:
        raise ScenarioFileError(f"scenario {scenario.name} has no origin: it cannot be flown")
    plans = _plans(scenario, args)
    if not any(plan.feasible for plan in plans):
        raise ScenarioFileError(f"no safe plan for {scenario.name}: {plans[0].conflicts[:1]}")
    try:
        return asyncio.run(_fly(scenario, plans, urls, args))
    except GcsError as exc:
        print(f"mvo-gcs fly: {exc}", file=sys.stderr)
        return 1


def _plans(scenario: Scenario, args: argparse.Namespace) -> list[Plan]:
    """One plan per candidate (`gcs.mission.flight_choice`)."""
    from planner.pipeline import plan

    seeds = f"{args.candidates} candidates" if args.candidates > 1 else f"seed {args.seed}"
    print(f"planning {scenario.name} with {args.algorithm} ({seeds}) ...", flush=True)
    settings, count = planner_settings(args), args.candidates
    return [
        plan(candidate(scenario, args.clearance, k), settings.candidate(k, count))
        for k in range(count)
    ]


async def _fly(
    scenario: Scenario, plans: list[Plan], urls: list[str], args: argparse.Namespace
) -> int:
    links = await _connect(scenario, urls, args.connect_timeout)
    try:
        try:
            choice = await _flight(plans, scenario, links, args)
        except (UnsafeSpeed, FlightStuck) as exc:
            print(f"mvo-gcs fly: {_refusal(exc)}; nothing was armed", file=sys.stderr)
            return 2
        if args.dry_run:
            _print_timing(choice.flight)
            return 0
        settings = FleetSettings(
            fallback=Fallback(args.on_failure), link_loss_brake_s=args.link_loss_brake
        )
        fleet = Fleet(links, choice.flight, settings=settings)
        display = ProgressDisplay()
        watcher = asyncio.create_task(_show(fleet, display))
        report = await fleet.fly()
        await asyncio.wait({watcher}, timeout=5.0)
        return _summary(report, choice.plan, scenario)
    finally:
        await asyncio.gather(*(link.close() for link in links.values()))


async def _connect(scenario: Scenario, urls: list[str], timeout: float) -> dict[str, VehicleLink]:
    from gcs.mavlink.link import LinkSettings

    settings = LinkSettings(connect_timeout_s=timeout)
    tasks = [client.connect(url, settings=settings) for url in urls]
    results = await asyncio.gather(*tasks, return_exceptions=True)
    links, problems = {}, []
    for uav, url, result in zip(scenario.uavs, urls, results, strict=True):
        if isinstance(result, BaseException):
            problems.append(f"{uav.id} ({url}): {result}")
        else:
            links[uav.id] = result
            print(f"{uav.id}: {result.autopilot.name} sysid {result.sysid} on {url}", flush=True)
    if problems:
        await asyncio.gather(*(link.close() for link in links.values()))
        raise GcsError("cannot reach every vehicle: " + "; ".join(problems))
    return links


async def _flight(
    plans: list[Plan], scenario: Scenario, links: dict[str, VehicleLink], args: argparse.Namespace
) -> Choice:
    """The plan flown soonest at `--max-speed` with each vehicle's own limits, timed and
    ordered."""
    read = await asyncio.gather(*(read_limits(link) for link in links.values()))
    limits = dict(zip(links, read, strict=True))
    autopilots = {uav: link.autopilot for uav, link in links.items()}

    def fly_as(plan: Plan) -> FlightPlan:
        return flight_plan(
            plan,
            scenario,
            autopilots,
            altitude_m=args.altitude,
            finish=args.finish,
            max_speed_m_s=args.max_speed,
            turn_radius_m=args.turn_radius,
            limits=limits,
        )

    choice = soonest(plans, fly_as)
    if len(plans) > 1:
        print(f"candidates timed at {args.max_speed:g} m/s:", flush=True)
        for trial in choice.trials:
            clearance = args.clearance + (trial.seed - args.seed) * WIDER_M
            chosen = " (flown)" if trial.seed == choice.plan.seed else ""
            which = f"seed {trial.seed}, clearance {clearance:g} m"
            print(f"  {which}: {trial.outcome()}{chosen}", flush=True)
    flight = choice.flight
    what = "timed" if args.dry_run else "flying"
    print(
        f"{what} at up to {flight.speed_m_s:g} m/s, keeping the plan's passing order: "
        f"{flight.duration_s:.1f} s to the last goal when nothing goes wrong",
        flush=True,
    )
    return choice


def _refusal(exc: UnsafeSpeed | FlightStuck) -> str:
    if isinstance(exc, UnsafeSpeed):
        return str(exc)
    return f"these vehicles cannot keep the plan's passing order ({exc}): plan it again"


def _print_timing(flight: FlightPlan) -> None:
    """Each UAV's arrival over its goal and whom it lets pass first on the way."""
    for uav, timed in flight.timed.items():
        leaders = flight.leaders(uav)
        after = f", letting {', '.join(leaders)} pass first" if leaders else ""
        print(f"{uav}: over its goal at {timed.arrival_s:.1f} s{after}")
    print("dry run: nothing was uploaded or armed")


async def _show(fleet: Fleet, display: ProgressDisplay) -> None:
    async for event in fleet.events():
        display.show(event)


def _summary(report: FlightReport, plan: Plan, scenario: Scenario) -> int:
    radius = max(u.radius for u in scenario.uavs) * scenario.grid.cell_size_m
    planned = plan.metrics.min_separation
    planned_m = f"{planned * scenario.grid.cell_size_m:.2f} m" if planned is not None else "-"
    flown = report.min_separation_m
    flown_text = (
        f"{flown:.2f} m between {' and '.join(report.closest_pair or ())}"
        if (flown is not None)
        else "- (fewer than two vehicles airborne together)"
    )
    print(f"separation flown: {flown_text}; plan: {planned_m}; required 2R: {2 * radius:.2f} m")
    for uav, why in report.failed.items():
        print(f"{uav}: {why}", file=sys.stderr)
    if not report.completed:
        print("mvo-gcs fly: the flight did not complete", file=sys.stderr)
        return 1
    if flown is not None and flown < 2 * radius:
        print("mvo-gcs fly: the vehicles came closer than 2R", file=sys.stderr)
        return 1
    return 0

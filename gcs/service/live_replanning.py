"""A non-UAV object reported during a flight: replan only the UAVs it touches.

The planner decides who changes and how (`planner.live.replan`, the wormhole step done
live); this module gives it the fleet's clock and positions, turns the new trajectories
into missions, re-uploads only those, and splices them into the flight's current plan
so that the next report starts from what the vehicles are really flying.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass

import numpy as np

from gcs.fleet.fleet import Fleet, VehicleOutcome
from gcs.mavlink.mission_item import Mission
from gcs.mission.build import Finish, build_mission
from gcs.mission.flight_plan import FlightPlan
from gcs.mission.geodesy import GridFrame
from planner.live.replan import LiveReplan, NewObject, replan_live
from planner.model.plan import Plan, PlannedUAV
from planner.model.scenario import Scenario
from planner.model.trajectory import Trajectory


@dataclass(frozen=True)
class ReplanOutcome:
    result: LiveReplan
    missions: dict[str, Mission]  # what was sent to each changed UAV's vehicle
    uploads: dict[str, VehicleOutcome[None]]
    plan: Plan  # the flight's plan with the new trajectories spliced in


async def replan_flight(
    fleet: Fleet,
    scenario: Scenario,
    plan: Plan,
    new_object: NewObject,
    known: list[NewObject],
    *,
    altitude_m: float,
    finish: Finish,
    turn_radius_m: float,
) -> ReplanOutcome:
    """`scenario` and `plan` are as flown (at the flight's speed): the fleet's clock is the
    plan's, and each vehicle's place on its own plan is where its remaining flight starts
    (flown by the passing order, vehicles are ahead of or behind that clock)."""
    frame = GridFrame.of(scenario)
    now = fleet.plan_time()
    positions = _positions(fleet, frame, scenario.grid.cell_size_m)
    progress = {uav: t for uav, t in fleet.places_on_plan().items() if uav in positions}
    along, committed = fleet.along(), fleet.committed()
    speeds = {u.id: u.speed for u in scenario.uavs}
    autopilots = {u.id: fleet.autopilot(u.id) for u in scenario.uavs}

    def replanned() -> tuple[LiveReplan, dict[str, Mission], FlightPlan | None]:
        """The replan, its missions and the rest of the flight with them, in one worker
        call: a flight whose new passing order cannot be kept (FlightStuck) is found here,
        before anything is uploaded."""
        result = replan_live(
            scenario, plan, new_object, now=now, positions=positions, progress=progress,
            known_objects=known,
        )  # fmt: skip
        missions = {
            uav: build_mission(
                trajectory.points,
                speeds[uav],
                frame,
                autopilots[uav],
                altitude_m=altitude_m,
                finish=finish,
                acceptance_radius_m=turn_radius_m,
                holds=False,  # the passing order makes it wait where another is in its way
                airborne=True,
            )
            for uav, trajectory in result.changed.items()
        }
        if not missions:
            return result, missions, None
        return (
            result,
            missions,
            fleet.continuation(along, result.changed, missions, result.now, committed=committed),
        )

    result, missions, rest = await asyncio.to_thread(replanned)
    uploads = (
        await fleet.replan(missions, dict(result.changed), starts_at=result.now, checked=rest)
        if rest is not None
        else {}
    )
    return ReplanOutcome(result, missions, uploads, _spliced(plan, result, uploads))


def _positions(fleet: Fleet, frame: GridFrame, cell_m: float) -> dict[str, tuple[float, float]]:
    """Where each airborne vehicle starts a new path from (cells): where it comes to
    rest once stopped for it, if it flies on, else where it is."""
    stopping = fleet.stopping_places()
    where = {}
    for progress in fleet.progress():
        if progress.lat is not None and progress.lon is not None and not progress.finished:
            if progress.uav_id in stopping:
                east, north = stopping[progress.uav_id]
                where[progress.uav_id] = (east / cell_m, north / cell_m)
            else:
                x, y = frame.to_cells(progress.lat, progress.lon)
                where[progress.uav_id] = (float(x), float(y))
    return where


def _spliced(plan: Plan, result: LiveReplan, uploads: dict[str, VehicleOutcome[None]]) -> Plan:
    """The plan as flown from now on: old trajectories up to `now`, then the new ones
    (only for the vehicles that took their new mission)."""
    uavs: list[PlannedUAV] = []
    for u in plan.uavs:
        outcome = uploads.get(u.id)
        if outcome is None or not outcome.ok:
            uavs.append(u)
            continue
        new = result.changed[u.id].points
        old = np.asarray(u.trajectory, dtype=float)
        flown = Trajectory(np.vstack([old[old[:, 0] < new[0, 0]], new]))
        uavs.append(
            u.model_copy(
                update={
                    "trajectory": flown.to_json(),
                    "replanned": [*u.replanned, "non-UAV object reported in flight"],
                }
            )
        )
    return plan.model_copy(update={"uavs": uavs})

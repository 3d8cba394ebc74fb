"""A plan's MAVLink missions: the items per UAV, and QGroundControl / ArduPilot files.

They are the missions a flight of the plan would upload, timed the same way (the plan
at `max_speed_m_s` for its fastest UAV, corners within `turn_radius_m`). What a file
cannot carry is the passing order, which only the ground station keeps while they fly:
a `.plan` says in its notes whom its UAV must let pass first. What a flight actually
uploaded is at `/flights/{id}/missions/{uav}.plan`.
"""

from __future__ import annotations

import asyncio
from dataclasses import asdict
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query
from fastapi.responses import PlainTextResponse
from pydantic import BaseModel

from gcs.mavlink.mission_item import Autopilot, Mission
from gcs.mission.files import plan_text, waypoints_text
from gcs.mission.flight_plan import FlightPlan, UnsafeSpeed, flight_plan
from gcs.service.api.deps import PlansDep, ScenariosDep
from gcs.service.api.schemas import UNSAFE_SPEED, MissionShape, Problem
from gcs.service.storage import NotFound
from planner.plan import Plan
from planner.scenario import Scenario

router = APIRouter(tags=["missions"])
AutopilotName = Literal["ardupilot", "px4"]
ANSWERS: dict[int | str, dict[str, Any]] = {
    404: {"model": Problem, "description": "no such plan or UAV"},
    409: {"model": Problem, "description": "the plan cannot be flown (infeasible, no origin)"},
    **UNSAFE_SPEED,
}


class MissionItemOut(BaseModel):
    seq: int
    command: int
    frame: int
    params: list[float | None]  # NaN as null, as QGroundControl writes it
    x: int  # latitude, degE7
    y: int  # longitude, degE7
    z: float
    autocontinue: bool


class MissionOut(BaseModel):
    uav_id: str
    autopilot: AutopilotName
    items: list[MissionItemOut]


class MissionOptions(MissionShape):
    autopilot: AutopilotName = "ardupilot"


Options = Annotated[MissionOptions, Query()]


class UnflyablePlan(Exception):
    """The plan exists but cannot become missions; answered 409."""


async def plan_flight(
    plans: PlansDep, scenarios: ScenariosDep, plan_id: str, options: MissionOptions
) -> FlightPlan:
    row = await plans.get(plan_id)
    scenario = Scenario(**(await scenarios.get(row.scenario_id)).body)
    plan = Plan(**row.body)
    autopilot = Autopilot[options.autopilot.upper()]
    try:
        flight = await asyncio.to_thread(
            flight_plan,
            plan,
            scenario,
            dict.fromkeys((u.id for u in plan.uavs), autopilot),
            altitude_m=options.altitude_m,
            finish=options.finish,
            max_speed_m_s=options.max_speed_m_s,
            turn_radius_m=options.turn_radius_m,
        )
    except UnsafeSpeed:
        raise
    except ValueError as exc:
        raise UnflyablePlan(str(exc)) from exc
    return flight


async def _one(
    plans: PlansDep, scenarios: ScenariosDep, plan_id: str, uav_id: str, options: MissionOptions
) -> tuple[Mission, str]:
    """The UAV's mission and the notes its file carries."""
    flight = await plan_flight(plans, scenarios, plan_id, options)
    if uav_id not in flight.missions:
        raise NotFound(f"UAV in plan {plan_id}", uav_id)
    return flight.missions[uav_id], flight.notes(uav_id)


def mission_out(uav_id: str, mission: Mission) -> MissionOut:
    items = [
        MissionItemOut(
            seq=seq,
            **{k: v for k, v in asdict(item).items() if k != "params"},
            params=[None if p != p else p for p in item.params],
        )
        for seq, item in enumerate(mission.items)
    ]
    autopilot: AutopilotName = "px4" if mission.autopilot == Autopilot.PX4 else "ardupilot"
    return MissionOut(uav_id=uav_id, autopilot=autopilot, items=items)


@router.get("/plans/{plan_id}/missions", operation_id="planMissions", responses=ANSWERS)
async def get_missions(
    plan_id: str, plans: PlansDep, scenarios: ScenariosDep, options: Options
) -> list[MissionOut]:
    """One MISSION_ITEM_INT list per UAV (ArduPilot: item 0 is home)."""
    flight = await plan_flight(plans, scenarios, plan_id, options)
    return [mission_out(u, m) for u, m in flight.missions.items()]


@router.get(
    "/plans/{plan_id}/missions/{uav_id}.plan",
    response_model=None,
    responses={**ANSWERS, 200: {"description": "a QGroundControl .plan (JSON) file"}},
)
async def download_qgc_plan(
    plan_id: str, uav_id: str, plans: PlansDep, scenarios: ScenariosDep, options: Options
) -> PlainTextResponse:
    """The UAV's mission as a QGroundControl `.plan` file, as a flight would fly it, with
    notes on the passing order it cannot keep alone."""
    text = plan_text(*await _one(plans, scenarios, plan_id, uav_id, options))
    return _attachment(text, f"{uav_id}.plan", "application/json")


@router.get(
    "/plans/{plan_id}/missions/{uav_id}.waypoints",
    response_model=None,
    responses={
        **ANSWERS,
        200: {
            "description": "a QGC WPL 110 file",
            "content": {"text/plain": {"schema": {"type": "string"}}},
        },
    },
)
async def download_waypoints(
    plan_id: str, uav_id: str, plans: PlansDep, scenarios: ScenariosDep, options: Options
) -> PlainTextResponse:
    """The UAV's mission as a `QGC WPL 110` file (Mission Planner, MAVProxy), as a flight
    would fly it (the format has no room for notes: see the `.plan`)."""
    mission, _ = await _one(plans, scenarios, plan_id, uav_id, options)
    text = waypoints_text(mission)
    return _attachment(text, f"{uav_id}.waypoints", "text/plain")


def _attachment(text: str, name: str, media_type: str) -> PlainTextResponse:
    return PlainTextResponse(
        text,
        media_type=media_type,
        headers={"Content-Disposition": f'attachment; filename="{name}"'},
    )

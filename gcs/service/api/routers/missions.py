"""A plan's MAVLink missions: the items per UAV, and QGroundControl / ArduPilot files."""

from __future__ import annotations

from dataclasses import asdict
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query
from fastapi.responses import PlainTextResponse
from pydantic import BaseModel, Field

from gcs.mavlink.mission_item import Autopilot, Mission
from gcs.mission.build import DEFAULT_ALTITUDE_M, build_missions
from gcs.mission.files import plan_text, waypoints_text
from gcs.service.api.deps import ServicesDep
from gcs.service.api.schemas import Problem
from gcs.service.storage import NotFound
from planner.plan import Plan
from planner.scenario import Scenario

router = APIRouter(tags=["missions"])
AutopilotName = Literal["ardupilot", "px4"]
ANSWERS: dict[int | str, dict[str, Any]] = {
    404: {"model": Problem, "description": "no such plan or UAV"},
    409: {"model": Problem, "description": "the plan cannot be flown (infeasible, no origin)"},
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


class MissionOptions(BaseModel):
    autopilot: AutopilotName = "ardupilot"
    altitude_m: float = Field(default=DEFAULT_ALTITUDE_M, gt=0, le=1000, description="above home")
    finish: Literal["land", "rtl"] = "land"


Options = Annotated[MissionOptions, Query()]


class UnflyablePlan(Exception):
    """The plan exists but cannot become missions; answered 409."""


def plan_missions(
    services: ServicesDep, plan_id: str, options: MissionOptions
) -> dict[str, Mission]:
    row = services.plans.get(plan_id)
    scenario = Scenario(**services.scenarios.get(row.scenario_id).body)
    try:
        return build_missions(
            Plan(**row.body),
            scenario,
            Autopilot[options.autopilot.upper()],
            altitude_m=options.altitude_m,
            finish=options.finish,
        )
    except ValueError as exc:
        raise UnflyablePlan(str(exc)) from exc


def _one(services: ServicesDep, plan_id: str, uav_id: str, options: MissionOptions) -> Mission:
    missions = plan_missions(services, plan_id, options)
    if uav_id not in missions:
        raise NotFound(f"UAV in plan {plan_id}", uav_id)
    return missions[uav_id]


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


@router.get("/plans/{plan_id}/missions", responses=ANSWERS)
def get_missions(plan_id: str, services: ServicesDep, options: Options) -> list[MissionOut]:
    """One MISSION_ITEM_INT list per UAV (ArduPilot: item 0 is home)."""
    return [mission_out(u, m) for u, m in plan_missions(services, plan_id, options).items()]


@router.get(
    "/plans/{plan_id}/missions/{uav_id}.plan",
    response_model=None,
    responses={**ANSWERS, 200: {"description": "a QGroundControl .plan (JSON) file"}},
)
def download_qgc_plan(
    plan_id: str, uav_id: str, services: ServicesDep, options: Options
) -> PlainTextResponse:
    """The UAV's mission as a QGroundControl `.plan` file."""
    text = plan_text(_one(services, plan_id, uav_id, options))
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
def download_waypoints(
    plan_id: str, uav_id: str, services: ServicesDep, options: Options
) -> PlainTextResponse:
    """The UAV's mission as a `QGC WPL 110` file (Mission Planner, MAVProxy)."""
    text = waypoints_text(_one(services, plan_id, uav_id, options))
    return _attachment(text, f"{uav_id}.waypoints", "text/plain")


def _attachment(text: str, name: str, media_type: str) -> PlainTextResponse:
    return PlainTextResponse(
        text,
        media_type=media_type,
        headers={"Content-Disposition": f'attachment; filename="{name}"'},
    )

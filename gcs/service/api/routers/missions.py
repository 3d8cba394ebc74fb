"""A plan's MAVLink missions: the items per UAV, and QGroundControl / ArduPilot files;
and the flight they make, timed.

They are the missions a flight of the plan would upload, timed the same way (the plan
at `max_speed_m_s` for its fastest UAV, corners within `turn_radius_m`). What a file
cannot carry is the passing order, which only the ground station keeps while they fly:
a `.plan` says in its notes whom its UAV must let pass first. What a flight actually
uploaded is at `/flights/{id}/missions/{uav}.plan`.

The timing (`/plans/{id}/timing`) is the flight at those options when nothing goes
wrong: a faster cruise is not always a sooner arrival (each wait of the passing order is
a longer stop and start at speed), so an operator can compare a few speeds before flying.

They are made once per plan and options, off the event loop, and kept
(`gcs.service.mission_files`): many readers cost one computation.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query
from fastapi.responses import PlainTextResponse, Response

from gcs.service.api.deps import MissionFilesDep
from gcs.service.api.schemas import UNSAFE_SPEED, MissionShape, Problem
from gcs.service.mission_files import (
    AutopilotName,
    MissionItemOut,
    MissionOut,
    Shape,
    TimingOut,
    UnflyablePlan,
    mission_out,
)

__all__ = ["MissionItemOut", "MissionOut", "TimingOut", "UnflyablePlan", "mission_out", "router"]

router = APIRouter(tags=["missions"])
ANSWERS: dict[int | str, dict[str, Any]] = {
    404: {"model": Problem, "description": "no such plan or UAV"},
    409: {
        "model": Problem,
        "description": "the plan cannot be flown (infeasible, no origin; for its timing, a "
        "passing order that cannot be kept to the end)",
    },
    **UNSAFE_SPEED,
}


class MissionOptions(MissionShape):
    autopilot: AutopilotName = "ardupilot"

    def shape(self) -> Shape:
        return Shape(
            autopilot=self.autopilot,
            altitude_m=self.altitude_m,
            finish=self.finish,
            max_speed_m_s=self.max_speed_m_s,
            turn_radius_m=self.turn_radius_m,
        )


Options = Annotated[MissionOptions, Query()]


@router.get(
    "/plans/{plan_id}/missions",
    operation_id="planMissions",
    response_model=list[MissionOut],
    responses=ANSWERS,
)
async def get_missions(plan_id: str, files: MissionFilesDep, options: Options) -> Response:
    """One MISSION_ITEM_INT list per UAV (ArduPilot: item 0 is home)."""
    body = await files.missions(plan_id, options.shape())
    return Response(body, media_type="application/json")


@router.get(
    "/plans/{plan_id}/timing",
    operation_id="planTiming",
    response_model=TimingOut,
    responses=ANSWERS,
)
async def get_timing(plan_id: str, files: MissionFilesDep, options: Options) -> Response:
    """How long a flight of the plan at these options takes when nothing goes wrong, with
    ArduCopter's default limits (a flight times it again with its vehicles' own): each
    UAV's arrival over its goal and whom it lets pass first on the way."""
    body = await files.timing(plan_id, options.shape())
    return Response(body, media_type="application/json")


@router.get(
    "/plans/{plan_id}/missions/{uav_id}.plan",
    response_model=None,
    responses={**ANSWERS, 200: {"description": "a QGroundControl .plan (JSON) file"}},
)
async def download_qgc_plan(
    plan_id: str, uav_id: str, files: MissionFilesDep, options: Options
) -> PlainTextResponse:
    """The UAV's mission as a QGroundControl `.plan` file, as a flight would fly it, with
    notes on the passing order it cannot keep alone."""
    text = await files.plan_file(plan_id, uav_id, options.shape())
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
    plan_id: str, uav_id: str, files: MissionFilesDep, options: Options
) -> PlainTextResponse:
    """The UAV's mission as a `QGC WPL 110` file (Mission Planner, MAVProxy), as a flight
    would fly it (the format has no room for notes: see the `.plan`)."""
    text = await files.waypoints_file(plan_id, uav_id, options.shape())
    return _attachment(text, f"{uav_id}.waypoints", "text/plain")


def _attachment(text: bytes, name: str, media_type: str) -> PlainTextResponse:
    return PlainTextResponse(
        text,
        media_type=media_type,
        headers={"Content-Disposition": f'attachment; filename="{name}"'},
    )

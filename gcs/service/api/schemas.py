"""What the API takes and gives. Scenarios and plans are the planner's own models."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, TypeAdapter, field_validator

from gcs.mission.build import DEFAULT_ALTITUDE_M
from gcs.mission.flight_choice import MAX_CANDIDATES, WIDER_M
from gcs.mission.flight_plan import DEFAULT_CLEARANCE_M, MAX_SPEED_M_S, TURN_RADIUS_M
from gcs.mission.motion import DEFAULT_SPEED_M_S
from gcs.service.states import JobState
from planner.model.plan import Metrics, Plan
from planner.model.scenario import Scenario
from planner.optimizers import ALGORITHMS

MAX_PAGE = 200
"""The most rows one list answer carries (each summarised): a bound on its size."""


def _utc(value: datetime) -> datetime:
    """SQLite forgets the zone it was given; every stored time is UTC."""
    return value if value.tzinfo else value.replace(tzinfo=UTC)


UtcDatetime = Annotated[datetime, AfterValidator(_utc)]


class _In(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


class _Out(BaseModel):
    model_config = ConfigDict(from_attributes=True)


class MissionShape(BaseModel):
    """How a plan becomes missions: the same options for a flight and for mission files,
    so that a file flies as the service would fly it."""

    altitude_m: float = Field(default=DEFAULT_ALTITUDE_M, gt=0, le=1000, description="above home")
    finish: Literal["land", "rtl"] = "land"
    max_speed_m_s: float = Field(
        default=DEFAULT_SPEED_M_S,
        gt=0,
        le=MAX_SPEED_M_S,
        description="the cruise speed of the plan's fastest UAV (the others keep their "
        "relative speeds); a speed the ground station cannot keep safe for the plan and "
        "its vehicles is refused with 422, naming the highest one it can",
    )
    turn_radius_m: float = Field(
        default=TURN_RADIUS_M, ge=0, le=50, description="waypoint acceptance radius"
    )


class ScenarioOut(_Out):
    id: str
    name: str
    created_at: UtcDatetime
    scenario: Scenario
    geographic: dict[str, Any] | None = Field(
        default=None,
        description="the GeoJSON the grid scenario was derived from (posted as "
        "application/geo+json), as it was sent; null for a grid scenario",
    )


class ScenarioSummary(_Out):
    """A scenario in a list: what tells it apart (GET /scenarios/{id} gives all of it)."""

    id: str
    name: str
    created_at: UtcDatetime
    grid: list[int] = Field(description="[width, height] in cells")
    uavs: int


class PlanSummary(_Out):
    """A plan in a list: its verdict and metrics (GET /plans/{id} gives the paths)."""

    id: str
    scenario_id: str
    created_at: UtcDatetime
    feasible: bool
    algorithm: str
    objective: str
    metrics: Metrics


class PlanRequest(_In):
    algorithm: str = Field(default="mvo", description=f"one of {', '.join(sorted(ALGORITHMS))}")
    objective: Literal["qos", "paper"] = "qos"
    seed: int = Field(default=1, ge=0, le=2**32 - 1)
    population: int = Field(default=30, ge=2, le=500)
    iterations: int = Field(default=200, ge=1, le=100_000)
    time_budget_s: float | None = Field(
        default=5.0,
        gt=0,
        le=600,
        description="wall seconds for the whole plan: a safe plan as early as possible, "
        "improved while the budget lasts; null: no time bound, the iterations and "
        "`patience` bound it and the same seed gives the same plan",
    )
    clearance_m: float = Field(
        default=DEFAULT_CLEARANCE_M,
        ge=0,
        le=10,
        description="metres beyond 2R the plan keeps between UAVs (and beyond R from "
        "obstacles), room for vehicles straying off their paths in flight; the flight "
        "refuses a speed at which they may stray further than the plan leaves room for",
    )
    patience: int | None = Field(
        default=100,
        ge=1,
        le=100_000,
        description="an optimizer run stops after this many iterations without gain; "
        "null: every run does all of its iterations (as the paper's Algorithm 1)",
    )
    candidates: int = Field(
        default=1,
        ge=1,
        le=MAX_CANDIDATES,
        description="plan this many candidates (the k-th from 0: seed `seed` + k, clearance "
        f"`clearance_m` + {WIDER_M:g} k m) and keep the plan the vehicles fly soonest at "
        "`flight_speed_m_s` (timed as `/plans/{id}/timing` times it, with the default "
        "mission options): plans alike on the planner's clock can fly tens of seconds apart "
        "on copters. They share `time_budget_s`; the scenario needs an origin",
    )
    flight_speed_m_s: float = Field(
        default=DEFAULT_SPEED_M_S,
        gt=0,
        le=MAX_SPEED_M_S,
        description="the cruise speed candidates are timed at (with `candidates` above 1)",
    )
    wait_s: float | None = Field(
        default=None,
        ge=0,
        le=60,
        description="seconds to wait for the plan before answering 202 with a job "
        "(default: the service's setting)",
    )

    @field_validator("algorithm")
    @classmethod
    def _known(cls, name: str) -> str:
        key = name.lower()
        if key not in ALGORITHMS:
            raise ValueError(f"unknown algorithm {name!r}; choose one of {sorted(ALGORITHMS)}")
        return key


class CandidateOut(BaseModel):
    """One candidate of a plan chosen of several (`candidates` in the request)."""

    seed: int
    clearance_m: float = Field(description="metres beyond 2R it was planned to keep")
    duration_s: float | None = Field(
        description="its timed flight at the request's `flight_speed_m_s`: the common start "
        "to the last arrival; null when it cannot be flown (see `refusal`) or has the same "
        "paths as an earlier candidate (`same_as`)"
    )
    refusal: str | None = Field(description="why it cannot be flown at that speed")
    same_as: int | None = Field(description="the seed of an earlier candidate, same paths")
    kept: bool = Field(description="the plan is this candidate")


class PlanOut(_Out):
    id: str
    scenario_id: str
    created_at: UtcDatetime
    plan: Plan
    candidates: list[CandidateOut] | None = Field(
        default=None,
        description="what each candidate came to, in the order planned, when the plan was "
        "chosen of several (`candidates` above 1); null for a plan planned alone",
    )
    trajectories_wgs84: dict[str, list[list[float]]] | None = Field(
        default=None,
        description="per UAV id, its trajectory as [t, lat, lon] points (degrees, WGS84), "
        "piecewise linear like `plan.uavs[].trajectory`; null when the scenario has no origin",
    )


class JobOut(_Out):
    id: str
    scenario_id: str
    state: JobState
    percent: float
    best_cost: float | None
    first_safe_s: float | None = Field(
        default=None, description="when the job found its first safe plan"
    )
    plan_id: str | None
    error: str | None
    settings: dict[str, Any]
    created_at: UtcDatetime
    updated_at: UtcDatetime


class Claimant(BaseModel):
    """Another address sending as a vehicle's system id (ignored): an impostor, or the
    vehicle come back through a restarted router (`POST /vehicles/{id}/address`)."""

    address: str
    packets: int
    seconds_ago: float


class VehicleLive(BaseModel):
    """A vehicle's live state, as last heard: with the link down (`stale`) every value is
    the last one heard, `seconds_since_heard` ago."""

    model_config = ConfigDict(extra="forbid")

    online: bool = Field(description="its link is up")
    stale: bool = Field(description="not heard lately: the values are the last ones heard")
    sysid: int
    uid: str | None = Field(description="the board's unique id (AUTOPILOT_VERSION), in hex")
    autopilot: str = Field(examples=["ardupilot", "px4"])
    mode: str
    armed: bool
    airborne: bool
    system_status: int = Field(description="MAV_STATE")
    lat: float | None
    lon: float | None
    relative_alt_m: float | None
    groundspeed_m_s: float
    heading_deg: float
    mission_seq: int
    mission_total: int
    mission_state: int = Field(description="MISSION_STATE, 0 when the autopilot gives none")
    ignored_packets: int = Field(description="packets dropped: another sender, bad signature")
    claimed_from: Claimant | None
    seconds_since_heard: float | None


class VehicleUnheard(BaseModel):
    """A registered vehicle the service has no link to (yet), and why."""

    model_config = ConfigDict(extra="forbid")

    online: Literal[False]
    error: str = Field(examples=["cannot connect to tcp:127.0.0.1:5760: ..."])


LIVE: TypeAdapter[VehicleLive | VehicleUnheard] = TypeAdapter(VehicleLive | VehicleUnheard)
"""A registered vehicle's live state, from the registry's dict."""


class Problem(BaseModel):
    """Every 4xx answer: what is wrong, and where when it is in the request."""

    detail: str | list[dict[str, Any]]


class SpeedProblem(Problem):
    """A 422: the request is invalid, or asks for a speed the ground station cannot keep
    safe for this plan and these vehicles (then with the highest it can)."""

    highest_safe_speed_m_s: float | None = None


class GeographicProblem(Problem):
    """A 422: the request is invalid, or a geographic scenario describes nothing
    plannable (then `feature` names the feature at fault, e.g. `features[2] (start of
    'uav1')`, or is null when it is the file as a whole)."""

    feature: str | None = None


UNSAFE_SPEED: dict[int | str, dict[str, Any]] = {
    422: {
        "model": SpeedProblem,
        "description": "an invalid request, or a speed the ground station cannot keep safe "
        "for this plan and these vehicles (`highest_safe_speed_m_s` says what it can)",
    }
}

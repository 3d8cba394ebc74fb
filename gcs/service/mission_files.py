"""A plan's mission files and timing, made once per plan and options, off the event loop.

`GET /plans/{id}/missions`, `.../{uav}.plan` and `.waypoints` answer with what a flight of
the plan would upload: the plan paced at a speed (`flight_plan`: seconds of work for a
large plan) and rendered as JSON and files; `GET /plans/{id}/timing` with how long that
flight takes when nothing goes wrong (the timed flight: a simulation of every vehicle,
made only when asked for). Anyone may read them, so none of that work may run on the
event loop, where the operator's commands and the flight's followers run, and many
readers may not multiply it:

- the plan and its scenario are validated, the missions made (or the flight timed) and
  every answer rendered in a worker thread, once: the bytes of every answer are kept, per
  plan, options and kind, in a small LRU (`MAX_ENTRIES` combinations and `MAX_BYTES` of
  answers; a plan never changes once stored);
- identical requests while it is made wait for that one computation (single flight);
- at most `CONCURRENCY` computations run at once (a thread holding the GIL slows the
  loop: several would crowd it out); the others wait their turn without a thread;
- every request first reads whether the plan still exists (one indexed column, on a
  storage thread), so a deleted plan is 404 at once; deleting a plan or a scenario drops
  its entries (`forget`).

A refusal is a result too: 409 (`UnflyablePlan`) and 422 (`UnsafeSpeed`, with its
highest safe speed) are kept and answered again as they were made. Anything else (the
plan deleted while it was read, a storage error) is not kept.
"""

from __future__ import annotations

import asyncio
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any, Literal, Protocol, TypeVar

from prometheus_client import Counter, Gauge
from pydantic import BaseModel, Field, TypeAdapter
from sqlalchemy import select

from gcs.mavlink.mission_item import Autopilot, Mission
from gcs.mission.fence import fence_of
from gcs.mission.files import plan_text, waypoints_text
from gcs.mission.flight_plan import FlightPlan, UnsafeSpeed, flight_plan
from gcs.mission.flight_timing import FlightStuck
from gcs.mission.geographic import load_geographic
from gcs.service.metrics import ServiceMetrics
from gcs.service.storage import NotFound, PlanRepository, ScenarioRepository
from gcs.service.storage.tables import PlanRow
from planner.model.plan import Plan
from planner.model.scenario import Scenario

MAX_ENTRIES = 32
"""Plan and options combinations kept."""
MAX_BYTES = 64 * 2**20
"""Bytes of answers kept (a 100-UAV plan's are about 0.3 MB); the newest entry always."""
CONCURRENCY = 1
"""Computations at once: each holds the GIL for most of its run."""

AutopilotName = Literal["ardupilot", "px4"]


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


MISSIONS = TypeAdapter(list[MissionOut])


class UavTimingOut(BaseModel):
    uav_id: str
    arrival_s: float = Field(description="over its goal, seconds after the common start")
    lets_pass_first: list[str] = Field(
        description="the UAVs the passing order makes it wait for on the way"
    )


class TimingOut(BaseModel):
    """The flight of a plan at a speed when nothing goes wrong, as the ground station
    times it (each vehicle's S-curves, corners and stops, the passing order's waits, a
    lander in the others' way until it is down): the schedule flights are measured by."""

    max_speed_m_s: float
    duration_s: float = Field(description="from the common start to the last arrival")
    uavs: list[UavTimingOut]


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


class UnflyablePlan(Exception):
    """The plan exists but cannot become missions; answered 409."""


@dataclass(frozen=True)
class Shape:
    """How the plan becomes missions: the query's options."""

    autopilot: AutopilotName
    altitude_m: float
    finish: Literal["land", "rtl"]
    max_speed_m_s: float
    turn_radius_m: float

    def key(self) -> str:
        """Floats by `repr`: -0.0 and 0.0 are equal but may not render alike."""
        return repr(tuple(asdict(self).values()))


class Made(Protocol):
    @property
    def size(self) -> int: ...


M = TypeVar("M", bound=Made)
Maker = Callable[[dict[str, Any], dict[str, Any], Shape, dict[str, Any] | None], M]
"""A kind of answer made on a worker thread: (plan, scenario, shape, geographic)."""


@dataclass(frozen=True)
class Answers:
    """Every answer of one plan at one shape, rendered."""

    missions: bytes  # GET /plans/{id}/missions, as FastAPI would have serialized it
    plans: dict[str, bytes]  # the UAV's .plan
    waypoints: dict[str, bytes]  # the UAV's .waypoints

    @property
    def size(self) -> int:
        files = (*self.plans.values(), *self.waypoints.values())
        return len(self.missions) + sum(len(f) for f in files)


def answers(
    plan_body: dict[str, Any],
    scenario_body: dict[str, Any],
    shape: Shape,
    geographic: dict[str, Any] | None = None,
) -> Answers:
    """The work itself, on a worker thread: validation, pacing and rendering; the `.plan`
    files of a geographic scenario carry its fence and rally points."""
    fence = fence_of(load_geographic(geographic)) if geographic else None
    flight = _paced(plan_body, scenario_body, shape)
    missions = flight.missions
    return Answers(
        missions=MISSIONS.dump_json([mission_out(u, m) for u, m in missions.items()]),
        plans={
            u: plan_text(m, flight.notes(u), fence, shape.altitude_m).encode()
            for u, m in missions.items()
        },
        waypoints={u: waypoints_text(m).encode() for u, m in missions.items()},
    )


@dataclass(frozen=True)
class Timing:
    """`GET /plans/{id}/timing`'s answer, rendered."""

    body: bytes

    @property
    def size(self) -> int:
        return len(self.body)


def timing(
    plan_body: dict[str, Any],
    scenario_body: dict[str, Any],
    shape: Shape,
    geographic: dict[str, Any] | None = None,
) -> Timing:
    """The flight timed, on a worker thread, with ArduCopter's default limits (a flight
    times it again with its vehicles' own). A passing order that cannot be kept to the
    end is a 409, as at upload."""
    flight = _paced(plan_body, scenario_body, shape)
    try:
        timed = flight.timed
    except FlightStuck as exc:
        raise UnflyablePlan(f"its passing order cannot be kept ({exc}): plan it again") from None
    uavs = [
        UavTimingOut(
            uav_id=uav,
            arrival_s=round(t.arrival_s, 2),
            lets_pass_first=flight.leaders(uav),
        )
        for uav, t in timed.items()
    ]
    out = TimingOut(
        max_speed_m_s=flight.speed_m_s, duration_s=round(flight.duration_s, 2), uavs=uavs
    )
    return Timing(out.model_dump_json().encode())


def _paced(plan_body: dict[str, Any], scenario_body: dict[str, Any], shape: Shape) -> FlightPlan:
    """The plan paced at the shape's speed: UnsafeSpeed (422) or UnflyablePlan (409)."""
    scenario = Scenario(**scenario_body)
    plan = Plan(**plan_body)
    autopilot = Autopilot[shape.autopilot.upper()]
    try:
        return flight_plan(
            plan,
            scenario,
            dict.fromkeys((u.id for u in plan.uavs), autopilot),
            altitude_m=shape.altitude_m,
            finish=shape.finish,
            max_speed_m_s=shape.max_speed_m_s,
            turn_radius_m=shape.turn_radius_m,
        )
    except UnsafeSpeed:
        raise
    except ValueError as exc:
        raise UnflyablePlan(str(exc)) from exc


@dataclass
class _Entry:
    plan_id: str
    scenario_id: str
    made: asyncio.Task[Any]  # of the kind's Made
    size: int = 0


class MissionFiles:
    """The mission endpoints' answers, cached; one per service."""

    def __init__(
        self,
        plans: PlanRepository,
        scenarios: ScenarioRepository,
        metrics: ServiceMetrics | None = None,
        *,
        max_entries: int = MAX_ENTRIES,
        max_bytes: int = MAX_BYTES,
        concurrency: int = CONCURRENCY,
    ) -> None:
        self.plans, self.scenarios = plans, scenarios
        self.max_entries, self.max_bytes = max_entries, max_bytes
        self._entries: OrderedDict[tuple[str, str], _Entry] = OrderedDict()
        self._running = asyncio.Semaphore(concurrency)  # computations at once
        registry = metrics.registry if metrics is not None else None
        self.computations = Counter(
            "mvo_gcs_mission_computations",
            "plans made into missions or timed for the mission and timing endpoints (once "
            "per plan, options and kind while cached), by outcome",
            ["outcome"],
            registry=registry,
        )
        self.running = Gauge(
            "mvo_gcs_mission_computations_running",
            "mission-endpoint computations under way (at most one at a time)",
            registry=registry,
        )
        self.cached = Gauge(
            "mvo_gcs_mission_cache_bytes",
            "bytes of mission-endpoint answers kept",
            registry=registry,
        )

    async def missions(self, plan_id: str, shape: Shape) -> bytes:
        """`GET /plans/{id}/missions`: JSON, one MISSION_ITEM_INT list per UAV."""
        return (await self._kept(plan_id, shape, answers)).missions

    async def plan_file(self, plan_id: str, uav_id: str, shape: Shape) -> bytes:
        """The UAV's QGroundControl `.plan`."""
        return _of_uav((await self._kept(plan_id, shape, answers)).plans, plan_id, uav_id)

    async def waypoints_file(self, plan_id: str, uav_id: str, shape: Shape) -> bytes:
        """The UAV's `QGC WPL 110` file."""
        return _of_uav((await self._kept(plan_id, shape, answers)).waypoints, plan_id, uav_id)

    async def timing(self, plan_id: str, shape: Shape) -> bytes:
        """`GET /plans/{id}/timing`: JSON, the flight at the shape's speed, timed."""
        return (await self._kept(plan_id, shape, timing)).body

    def forget(self, *plan_ids: str, scenario_id: str | None = None) -> None:
        """Drop the entries of deleted plans (or of every plan of a deleted scenario)."""
        gone = set(plan_ids)
        for key, entry in list(self._entries.items()):
            if entry.plan_id in gone or entry.scenario_id == scenario_id:
                self._drop(key)

    def __len__(self) -> int:
        return len(self._entries)

    async def close(self) -> None:
        """Stop what is still to be made (the service stops)."""
        pending = [e.made for e in self._entries.values() if not e.made.done()]
        for task in pending:
            task.cancel()
        await asyncio.gather(*pending, return_exceptions=True)
        self._entries.clear()
        self.cached.set(0)

    async def _kept(self, plan_id: str, shape: Shape, maker: Maker[M]) -> M:
        """The maker's answer for the plan at the shape: kept, being made, or made now."""
        try:
            scenario_id = await self.plans.db.run(_scenario_of, self.plans, plan_id)
        except NotFound:
            self.forget(plan_id)  # deleted while it was being made: nothing kept of it
            raise
        key = (plan_id, f"{maker.__name__}{shape.key()}")
        entry = self._entries.get(key)
        if entry is None:
            made = asyncio.ensure_future(self._make(plan_id, scenario_id, shape, maker))
            entry = self._entries[key] = _Entry(plan_id, scenario_id, made)
            made.add_done_callback(lambda task: self._made(key, entry, task))
            self._evict(keep=key)
        else:
            self._entries.move_to_end(key)
        # shielded: a reader who gives up does not cancel the others' computation
        answer: M = await asyncio.shield(entry.made)
        return answer

    async def _make(self, plan_id: str, scenario_id: str, shape: Shape, maker: Maker[M]) -> M:
        async with self._running:
            plan = await self.plans.get(plan_id)
            scenario = await self.scenarios.get(scenario_id)
            self.running.inc()
            try:
                made = await asyncio.to_thread(
                    maker, plan.body, scenario.body, shape, scenario.geographic
                )
            except (UnflyablePlan, UnsafeSpeed) as exc:
                self.computations.labels(type(exc).__name__).inc()
                raise
            except BaseException:
                self.computations.labels("error").inc()
                raise
            finally:
                self.running.dec()
            self.computations.labels("made").inc()
            return made

    def _made(self, key: tuple[str, str], entry: _Entry, task: asyncio.Task[Any]) -> None:
        if self._entries.get(key) is not entry:
            return  # forgotten or evicted meanwhile
        if task.cancelled():
            self._drop(key)
            return
        failure = task.exception()  # retrieved: no "never retrieved" warning if unread
        if failure is not None and not isinstance(failure, UnflyablePlan | UnsafeSpeed):
            self._drop(key)  # not the plan's answer: the next request tries again
            return
        entry.size = task.result().size if failure is None else 0
        self.cached.inc(entry.size)
        self._evict(keep=key)

    def _evict(self, keep: tuple[str, str]) -> None:
        """Oldest first, down to the limits; the entry just made stays, and so do those
        being made (readers wait for them: there are no more of them than requests)."""
        total = sum(e.size for e in self._entries.values())
        for key in list(self._entries):
            if len(self._entries) <= self.max_entries and total <= self.max_bytes:
                break
            if key != keep and self._entries[key].made.done():
                total -= self._entries[key].size
                self._drop(key)

    def _drop(self, key: tuple[str, str]) -> None:
        entry = self._entries.pop(key)
        self.cached.dec(entry.size)


def _scenario_of(plans: PlanRepository, plan_id: str) -> str:
    """The plan's scenario, or NotFound: one indexed column, not the plan's body."""
    with plans.db.session() as s:
        found = s.scalar(select(PlanRow.scenario_id).where(PlanRow.id == plan_id))
    if found is None:
        raise NotFound("plan", plan_id)
    return str(found)


def _of_uav(files: dict[str, bytes], plan_id: str, uav_id: str) -> bytes:
    if uav_id not in files:
        raise NotFound(f"UAV in plan {plan_id}", uav_id)
    return files[uav_id]

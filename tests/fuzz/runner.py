"""One fuzzed flight, through the in-process service, on its own virtual clock.

The flight is made and flown through the API as an operator's client would, the operator's
actions are sent at their moments, and the invariants are watched all along:

- no two airborne vehicles closer than 2R, by the simulator's truth (a vehicle sent home
  is left out from then on: RTL flies straight home, outside the plan's order);
- every operator command is answered by every vehicle that is online, within 1 s;
- the flight ends (landed, aborted, ended; after a restart, resumed or aborted by the
  operator, as the case draws: a resumed flight that lands has every vehicle at its goal);
- every state change is one the transition table allows;
- every event the flight told its listeners is stored;
- no answer is a 5xx, and nothing raises where nobody catches it.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import io
import itertools
import json
import logging
import math
import random
import tempfile
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from unittest import mock

import httpx

from gcs.mission.geodesy import GridFrame, distance_m
from gcs.service import planning_pool
from gcs.service.states import FLIGHT_TRANSITIONS, FlightState
from planner.model.scenario import Scenario
from sitl_mock import Simulator
from sitl_mock.modes import FlightMode
from sitl_mock.virtual_time import VirtualTimeLoop
from tests.fuzz.cases import DEFAULT_MAX_UAVS, LATE_TAKE_OFF_S, Action, FuzzCase
from tests.inprocess.service import InProcessService, until
from tests.inprocess.vehicles import SimulatedVehicles, configs_at_starts

ALTITUDE_M = 10.0
_STOPPED = frozenset({"BRAKE", "LAND", "stopped"})
_EFFECTS = {
    "abort-land": frozenset({"LAND", "stopped"}),
    "abort-rtl": frozenset({"RTL", "LAND", "stopped"}),
    "land": frozenset({"LAND", "stopped"}),
    "rtl": frozenset({"RTL", "LAND", "stopped"}),
    "pause": _STOPPED,
    "hold": _STOPPED,
}
"""What a command must have made of each vehicle it reached within ANSWER_WITHIN_S: its
mode, or "stopped" (told to hold where it is, or down); unless a later command to it came
first."""
ANSWER_WITHIN_S = 1.0
_LANDINGS = {"abort-land", "land"}
LANDING_WITHIN_S = 15.0
"""A vehicle told to land is coming down (LAND) or down by then, whatever else the 1 s
check took for its effect ("stopped": holding where it is is not landing)."""
HELD_DRIFT_M = 2.0
"""How far a vehicle held by the operator may move once it stands (it hovers in place)."""
STANDING_M_S = 0.1
STAND_S = 1.0
"""How long a held vehicle must stay slower than STANDING_M_S to stand: one held just as
it set off from a waypoint is still at rest there for a moment, and its paused S-curve
then runs on a few metres (fuzzed flight 4116: 2.8 m)."""
ARRIVED_M = 1.0  # within this of its goal, a vehicle has arrived
GOAL_RADIUS_M = 2.0  # ArduCopter's WP_RADIUS_M: a mission's goal is reached within it
WATCH_EVERY_S = 0.1
END_WITHIN_S = 900.0
LINK_BACK_S = 5.0
"""After a link drop, the link is taken up again within this (the service's heartbeat
comes within 1 s, and a command under way still runs out its attempts)."""
REABORT_S = 300.0
"""An abort that has not brought everyone down by then (held after it, say) is given again."""
RESUME_AFTER_S = 30.0
"""How long the operator waits for every vehicle to be online again before a resume."""
FINAL = {"landed", "ended", "aborted"}
PLAN_REQUEST = {"time_budget_s": None, "iterations": 60, "population": 20, "wait_s": 60}
"""Iterations only: the same plan for the same scenario whatever the machine's load."""


@dataclass
class Report:
    case: FuzzCase
    violations: list[str] = field(default_factory=list)
    outcome: str = ""
    min_separation_m: float = math.inf
    landing_error_m: float = 0.0  # the furthest any vehicle came down from its goal
    mission_s: float | None = None  # the synchronised start to the last arrival over a goal
    timed_s: float | None = None  # the same, as the flight's timing has it
    two_r_m: float = 0.0
    virtual_s: float = 0.0
    notes: list[str] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)  # told live, but Progress

    def trace(self) -> str:
        """The flight's events, one a line: what to read when replaying a failure."""
        lines = []
        for event in self.events:
            rest = {k: v for k, v in event.items() if k not in ("type", "kind", "at")}
            lines.append(f"{event.get('at', 0.0):8.2f} {event['kind']:<18} {rest}")
        return "\n".join(lines)

    def waypoint_errors(self) -> list[float]:
        """Seconds each NAV item was reached after the timing said (before: negative),
        from the synchronised start, but the landing's (reached at touch-down)."""
        started = [e["at"] for e in self.events if e["kind"] == "MissionsStarted"]
        reached = [e for e in self.events if e["kind"] == "ItemReached"]
        if not started:
            return []
        by_uav: dict[str, list[dict[str, Any]]] = {}
        for event in reached:
            by_uav.setdefault(event["uav_id"], []).append(event)
        return [
            e["at"] - started[-1] - e["scheduled_s"]
            for events in by_uav.values()
            for e in events[:-1]
            if e["at"] >= started[-1]
        ]

    def summary(self) -> str:
        verdict = "OK" if not self.violations else f"{len(self.violations)} VIOLATIONS"
        lines = [
            f"{verdict}: {self.case.describe()}",
            f"  ended {self.outcome or '?'} after {self.virtual_s:.0f} virtual s; closest "
            f"{self.min_separation_m:.2f} m (2R {self.two_r_m:.2f} m)",
        ]
        if self.mission_s is not None and self.timed_s:
            lines.append(
                f"  mission {self.mission_s:.1f} s against {self.timed_s:.1f} s timed "
                f"({self.mission_s / self.timed_s:.2f}x); landed within "
                f"{self.landing_error_m:.2f} m of the goals"
            )
        lines += [f"  - {v}" for v in self.violations]
        lines += [f"  . {n}" for n in self.notes]
        if self.violations:
            drops = " --link-drops" if any(a.kind == "silence" for a in self.case.actions) else ""
            bound = self.case.max_uavs
            wider = f" --max-uavs {bound}" if bound != DEFAULT_MAX_UAVS else ""
            lines.append(f"  replay: python -m tests.fuzz --seed {self.case.seed}{wider}{drops}")
        return "\n".join(lines)


def fly_seed(seed: int, max_uavs: int = DEFAULT_MAX_UAVS, link_drops: bool = False) -> Report:
    """The seed's flight, in a data directory of its own (removed afterwards)."""
    with tempfile.TemporaryDirectory(prefix=f"fuzz-{seed}-") as tmp:
        return run(FuzzCase.draw(seed, max_uavs, link_drops), Path(tmp) / "data")


def fly_seed_quietly(
    seed: int, max_uavs: int = DEFAULT_MAX_UAVS, link_drops: bool = False
) -> Report:
    """`fly_seed` without the lines each in-process service prints when it starts (where
    its API and console are): a campaign prints its failing flights only. Here, not in
    `__main__`, so that Dask workers can import it."""
    with contextlib.redirect_stdout(io.StringIO()):
        return fly_seed(seed, max_uavs, link_drops)


def run(case: FuzzCase, data_dir: Path) -> Report:
    """The flight on a fresh virtual-time loop, its stored ids drawn from the seed: the
    service's commands go out in the order of its vehicles' ids, which uuid4 would make
    differ from run to run (flight 3519 came 5.76 m close in one run of eight)."""
    loop = VirtualTimeLoop(executor_delay=lambda: case.storage_delay_s)
    ids = random.Random(case.seed)
    with (
        mock.patch("uuid.uuid4", lambda: uuid.UUID(int=ids.getrandbits(128), version=4)),
        asyncio.Runner(loop_factory=lambda: loop) as runner,
    ):
        return runner.run(Flight(case, data_dir).fly())


class _Unheard:
    """Progress reports of a memoised plan: nobody listens."""

    def put(self, item: object) -> None:
        pass


@functools.cache
def _memo_plan(scenario: str, settings: str) -> planning_pool.PlanResult:
    return _plain_run_plan("fuzz", json.loads(scenario), json.loads(settings), _Unheard(), {})


_plain_run_plan = planning_pool.run_plan


def _memoised_run_plan(
    job_id: str,
    scenario: dict[str, Any],
    settings: dict[str, Any],
    progress: Any,
    cancelled: Any,
    *,
    cancel_each_iteration: bool = False,
    soonest_of: planning_pool.SoonestOf | None = None,
) -> planning_pool.PlanResult:
    """The planner, once per scenario and settings in this process (plans are pure; run_plan's
    signature, its progress and cancellation unused)."""
    if soonest_of is not None:  # (the fuzzer's flights plan one seed)
        return _plain_run_plan(
            job_id, scenario, settings, progress, cancelled, soonest_of=soonest_of
        )
    return _memo_plan(json.dumps(scenario, sort_keys=True), json.dumps(settings, sort_keys=True))


@dataclass(frozen=True)
class _Due:
    """A command's effect on one vehicle, to be seen by `at`."""

    action: Action
    sysid: int
    expected: frozenset[str]
    at: float
    within_s: float = ANSWER_WITHIN_S


class Flight:
    """One case flown, its invariants watched."""

    def __init__(self, case: FuzzCase, data_dir: Path) -> None:
        self.case = case
        self.data_dir = data_dir
        self.report = Report(case)
        self.vehicles = SimulatedVehicles()
        self.sim: Simulator | None = None
        self.service = InProcessService(data_dir, self.vehicles)
        self.flight_id = ""
        self.sent_home: set[int] = set()
        self.sent_away: set[int] = set()  # landed or sent home one by one by the operator
        self.held: set[int] = set()  # held one by one by the operator, not continued yet
        self.live: list[dict[str, Any]] = []
        self.due: list[_Due] = []  # effects of commands, not seen yet
        self.stopped_by: dict[int, Action] = {}  # held vehicles, by the hold that stopped them
        self.standing_at: dict[int, tuple[float, float]] = {}  # where each came to stand
        self.still_since: dict[int, float] = {}  # since when each held one is slow
        self.arrived: dict[int, float] = {}  # sysid: loop time over its goal
        self.silent: dict[int, tuple[float, float]] = {}  # link dropped, then taken up again
        self._sent_at = 0.0

    async def fly(self) -> Report:
        loop = asyncio.get_running_loop()
        loop.set_exception_handler(self._unhandled)
        planning_pool.run_plan = _memoised_run_plan
        errors = _ErrorLog(self.report)
        logging.getLogger("mvo_gcs").addHandler(errors)
        try:
            await self._fly()
        finally:
            logging.getLogger("mvo_gcs").removeHandler(errors)
            planning_pool.run_plan = _plain_run_plan
            await self.service.stop()
            await self.vehicles.stop()
            self.report.virtual_s = loop.time()
        return self.report

    async def _fly(self) -> None:
        scenario = self.case.scenario()
        self.report.two_r_m = 2 * max(u.radius for u in scenario.uavs) * scenario.grid.cell_size_m
        configs = configs_at_starts(scenario)
        for config in configs:
            config.faults = self.case.faults.get(config.sysid, config.faults)
            if config.sysid == self.case.late:
                config.estimate_delay_s = (config.estimate_delay_s or 0.0) + LATE_TAKE_OFF_S
        self.sim = await self.vehicles.start(configs, seed=self.case.seed)
        for sysid in self.sim.sysids:  # quicker landings: less simulated time per flight
            self.sim.set_param(sysid, "LAND_SPD_MS", 1.5)
        await self.service.start()
        if not await self._make(scenario):
            return
        watching = asyncio.ensure_future(self._watch(scenario))
        listening = asyncio.ensure_future(self._listen())
        try:
            await self._operate()
            await self._until_ended()
        finally:
            for task in (watching, listening):
                task.cancel()
            await asyncio.gather(watching, listening, return_exceptions=True)
        await self._check_records()
        if self.report.outcome == "landed":
            self._check_landings(scenario)
            self._time_the_mission()
        self.report.events = [m for m in self.live if m.get("kind") not in (None, "Progress")]

    # --- the flight through the API ---------------------------------------------------

    async def _make(self, scenario: Any) -> bool:
        client = self.service.client
        sid = await self._call("post", "/scenarios", json=scenario.model_dump(mode="json"))
        planned = await self._call(
            "post", f"/scenarios/{sid.json()['id']}/plans", json=PLAN_REQUEST
        )
        if planned.status_code != 201 or not planned.json()["plan"]["feasible"]:
            self.report.notes.append(f"no safe plan to fly ({planned.status_code})")
            return False
        assert self.sim is not None
        ids = []
        for sysid in self.sim.sysids:
            answer = await self._call(
                "post", "/vehicles", json={"connection": self.sim.connection_string(sysid)}
            )
            ids.append(answer.json()["id"])
        bindings = {u.id: v for u, v in zip(scenario.uavs, ids, strict=True)}
        made = await self._call(
            "post", "/flights",
            json={"plan_id": planned.json()["id"], "bindings": bindings,
                  "max_speed_m_s": self.case.speed_m_s, "altitude_m": ALTITUDE_M},
        )  # fmt: skip
        if made.status_code == 422:  # a speed refused before anything armed: as it should
            self.report.notes.append(f"speed refused: {made.json()['detail'][:120]}")
            self.report.outcome = "refused"
            return False
        self.flight_id = made.json()["id"]

        async def online() -> bool:
            listed = (await client.get("/vehicles")).json()
            return set(ids) <= {v["id"] for v in listed if v["live"]["online"]}

        await until(online, 60, "every vehicle online")
        uploaded = await self._call("post", f"/flights/{self.flight_id}/upload")
        if uploaded.status_code != 200 or uploaded.json()["flight"]["state"] != "uploaded":
            self.report.notes.append(f"upload did not complete: {uploaded.text[:200]}")
            self.report.outcome = "upload refused"
            return False
        return True

    async def _operate(self) -> None:
        """Start, then each operator action at its moment after the start was asked."""
        loop = asyncio.get_running_loop()
        started = loop.time()
        await self._call("post", f"/flights/{self.flight_id}/start")
        for action in self.case.actions:
            await asyncio.sleep(max(0.0, started + action.at_s - loop.time()))
            await self._act(action)

    async def _act(self, action: Action) -> None:
        flight = f"/flights/{self.flight_id}"
        if action.kind == "silence":  # the radio, not the operator: nothing to answer
            assert self.sim is not None and action.uav is not None and action.seconds
            now = asyncio.get_running_loop().time()
            self.sim.silence(action.uav, action.seconds)
            self.silent[action.uav] = (now, now + action.seconds + LINK_BACK_S)
            return
        self._supersede(action)
        self._sent_at = asyncio.get_running_loop().time()
        if action.kind == "restart":
            await self.service.restart()
            return
        if action.kind == "object":
            await self._call(
                "post", f"{flight}/objects", json={"cell": list(action.cell or (0, 0))}
            )
            return
        if action.uav is not None:
            vehicle = (await self.service.client.get(flight)).json()["bindings"][f"uav{action.uav}"]
            answer = await self._call("post", f"/vehicles/{vehicle}/{action.kind}")
            if action.kind == "rtl" and answer.status_code == 200:
                self.sent_home.add(action.uav)
            if action.kind in ("land", "rtl") and answer.status_code == 200:
                self.sent_away.add(action.uav)
            if answer.status_code == 200:
                (self.held.add if action.kind == "hold" else self.held.discard)(action.uav)
            self._check_answers(
                action, answer, [answer.json()] if answer.status_code == 200 else []
            )
            return
        if action.kind.startswith("abort"):
            answer = await self._call("post", f"{flight}/abort", json={"mode": action.kind[6:]})
            if action.kind == "abort-rtl" and answer.status_code == 200:
                assert self.sim is not None
                self.sent_home |= set(self.sim.sysids)
        else:
            answer = await self._call("post", f"{flight}/{action.kind}")
        vehicles = answer.json().get("vehicles", []) if answer.status_code == 200 else []
        self._check_answers(action, answer, vehicles)

    def _check_answers(
        self, action: Action, answer: httpx.Response, vehicles: list[dict[str, Any]]
    ) -> None:
        """A command is answered, by every vehicle that is online, and has its effect on
        each within 1 s of being sent (looked for in the simulator until then)."""
        if answer.status_code not in (200, 409):
            self.report.violations.append(
                f"{action.describe()}: answered {answer.status_code}: {answer.text[:200]}"
            )
        reached = []
        for vehicle in vehicles:
            if any(w in vehicle["detail"] for w in ("unreachable", "offline", "not commanded")):
                continue  # not online, or out of the flight (sent down or home before)
            if self._was_silent(vehicle["uav_id"]):
                continue  # its link dropped meanwhile: not reachable
            if not vehicle["ok"]:
                self.report.violations.append(
                    f"{action.describe()}: {vehicle['uav_id'] or vehicle['vehicle_id']} "
                    f"refused: {vehicle['detail']}"
                )
            elif vehicle["uav_id"]:
                reached.append(int(vehicle["uav_id"].removeprefix("uav")))
        expected = _EFFECTS.get(action.kind)
        if expected is not None:
            due = self._sent_at + ANSWER_WITHIN_S
            self.due += [_Due(action, sysid, expected, due) for sysid in reached]
        if action.kind in _LANDINGS:
            down, due = frozenset({"LAND", "down"}), self._sent_at + LANDING_WITHIN_S
            self.due += [_Due(action, sysid, down, due, LANDING_WITHIN_S) for sysid in reached]

    def _was_silent(self, uav_id: str | None) -> bool:
        """Whether the vehicle's link was dropped at any time since the command was sent."""
        if not uav_id:
            return False
        window = self.silent.get(int(uav_id.removeprefix("uav")))
        return (
            window is not None
            and window[0] <= asyncio.get_running_loop().time()
            and (window[1] >= self._sent_at)
        )

    def _supersede(self, action: Action) -> None:
        """A new command to a vehicle replaces what the last one was to do there."""
        self.due = [d for d in self.due if action.uav is not None and d.sysid != action.uav]
        for held in [u for u in self.stopped_by if action.uav is None or u == action.uav]:
            del self.stopped_by[held]
            self.standing_at.pop(held, None)
            self.still_since.pop(held, None)

    def _check_effects(self) -> None:
        """Each command's effect seen on each vehicle it reached, or a violation once due."""
        assert self.sim is not None
        now = asyncio.get_running_loop().time()
        waiting = []
        for due in self.due:
            state = self.sim.state(due.sysid)
            down = not state.armed or state.alt < 0.5
            if (
                state.mode in due.expected
                or (down and "down" in due.expected)
                or ((state.holding or down) and "stopped" in due.expected)
            ):
                if due.action.kind in ("pause", "hold") and state.armed:
                    self.stopped_by[due.sysid] = due.action
                continue
            if now >= due.at:
                self.report.violations.append(
                    f"{due.action.describe()}: uav{due.sysid} still in {state.mode} "
                    f"{due.within_s:g} s after"
                )
            else:
                waiting.append(due)
        self.due = waiting

    def _time_the_mission(self) -> None:
        """From the synchronised start to the last arrival, beside the timed flight's."""
        assert self.sim is not None
        started = [m for m in self.live if m.get("kind") == "MissionsStarted"]
        if started and set(self.arrived) == set(self.sim.sysids):
            self.report.mission_s = max(self.arrived.values()) - started[-1]["at"]
            self.report.timed_s = started[-1]["timed_duration_s"]

    def _check_landings(self, scenario: Scenario) -> None:
        """A `landed` flight has every vehicle down within the waypoint radius of its goal
        (by the simulator's truth), but those the operator landed or sent home itself."""
        assert self.sim is not None
        frame = GridFrame.of(scenario)
        for sysid, uav in zip(self.sim.sysids, scenario.uavs, strict=True):
            if sysid in self.sent_away:
                continue
            state = self.sim.state(sysid)
            lat, lon = frame.to_geodetic(*uav.goal)
            miss = distance_m(state.lat, state.lon, float(lat), float(lon))
            self.report.landing_error_m = max(self.report.landing_error_m, miss)
            if miss > GOAL_RADIUS_M or state.armed:
                self.report.violations.append(
                    f"{uav.id} came down {miss:.2f} m from its goal (armed: {state.armed})"
                )

    async def _until_ended(self) -> None:
        """Let go of what the operator holds and wait for the end; after a restart
        (interrupted), resume once if the case says so, and abort with LAND if it does not
        resume or does not say so, as when a flight held after its abort hovers on, as an
        operator would; a flight that does not end within the bound is a violation."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + END_WITHIN_S
        for uav in sorted(self.held):
            await self._act(Action(0.0, "continue", uav=uav))
        if (await self._state()) == "paused":
            await self._act(Action(0.0, "continue"))
        aborted_at, resumed = -math.inf, False
        while loop.time() < deadline:
            state = await self._state()
            if state in FINAL:
                self.report.outcome = state
                return
            stuck = state == "aborting" and loop.time() - aborted_at > REABORT_S
            restarted = any(a.kind == "restart" for a in self.case.actions)
            if state == "interrupted" and self.case.resume and restarted and not resumed:
                resumed = True
                if await self._resume():
                    continue
            if (state == "interrupted" and aborted_at < 0) or stuck:
                aborted_at = loop.time()
                await self._act(Action(0.0, "abort-land"))
            await asyncio.sleep(1.0)
        self.report.violations.append(f"the flight did not end within {END_WITHIN_S:.0f} s")

    async def _resume(self) -> bool:
        """The operator's resume of an interrupted flight, once every vehicle is online
        again (or after RESUME_AFTER_S); whether it flies again (a 409 is an answer: a
        vehicle offline, or its mission replanned live). A resume lets every vehicle go in
        the passing order, so the operator's holds before it no longer keep one still
        (fuzzed flight 3734 took a fleet hold sent while interrupted for still in force)."""

        async def online() -> bool:
            live = await self.service.client.get(f"/flights/{self.flight_id}/live-state")
            return live.status_code == 200 and all(v["online"] for v in live.json()["vehicles"])

        with contextlib.suppress(AssertionError):  # not all online: resumed all the same
            await until(online, RESUME_AFTER_S, "every vehicle online")
        self._supersede(Action(0.0, "continue"))  # a resume lets every vehicle go
        answer = await self._call("post", f"/flights/{self.flight_id}/resume")
        self.report.notes.append(f"resume: {answer.status_code} {answer.text[:160]}")
        if answer.status_code not in (200, 409):
            self.report.violations.append(f"resume: answered {answer.status_code}")
        return answer.status_code == 200 and await self._state() == "flying"

    async def _state(self) -> str:
        flight = (await self.service.client.get(f"/flights/{self.flight_id}")).json()
        return str(flight["state"])

    # --- watching ---------------------------------------------------------------------

    async def _watch(self, scenario: Scenario) -> None:
        """The simulator's truth every 0.1 s: no two airborne vehicles closer than 2R."""
        assert self.sim is not None
        sim, two_r = self.sim, self.report.two_r_m
        frame = GridFrame.of(scenario)
        goals = {}
        for sysid, uav in zip(sim.sysids, scenario.uavs, strict=True):
            lat, lon = frame.to_geodetic(*uav.goal)
            goals[sysid] = sim.to_local(float(lat), float(lon))
        while True:
            self._note_arrivals(goals)
            up = {
                sysid: (east, north)
                for sysid, (east, north, alt) in sim.local_positions().items()
                if alt > 1.0
                and sysid not in self.sent_home
                and sim.vehicle(sysid).flight.mode != FlightMode.RTL
            }
            for (a, pa), (b, pb) in itertools.combinations(sorted(up.items()), 2):
                gap = math.hypot(pa[0] - pb[0], pa[1] - pb[1])
                self.report.min_separation_m = min(self.report.min_separation_m, gap)
                if gap < two_r and len(self.report.violations) < 20:
                    self.report.violations.append(
                        f"uav{a} and uav{b} {gap:.2f} m apart (2R {two_r:.2f} m) at "
                        f"{asyncio.get_running_loop().time():.1f} s"
                    )
            self._check_effects()
            self._check_held_still()
            await asyncio.sleep(WATCH_EVERY_S)

    def _check_held_still(self) -> None:
        """A vehicle the operator held stays where it came to stand until the operator's
        next command to it (or to the fleet): nothing else may move it on."""
        assert self.sim is not None
        for sysid, action in list(self.stopped_by.items()):
            state = self.sim.state(sysid)
            if not state.armed or state.mode in ("LAND", "RTL"):
                continue
            east, north, _ = self.sim.local_positions()[sysid]
            standing = self.standing_at.get(sysid)
            if standing is None:
                self._note_standing(sysid, east, north)
                continue
            drift = math.hypot(east - standing[0], north - standing[1])
            if drift > HELD_DRIFT_M:
                self.report.violations.append(
                    f"{action.describe()}: uav{sysid} moved {drift:.1f} m while held"
                )
                del self.stopped_by[sysid]

    def _note_standing(self, sysid: int, east: float, north: float) -> None:
        assert self.sim is not None
        now = asyncio.get_running_loop().time()
        if math.hypot(*self.sim.vehicle(sysid).flight.body.velocity[:2]) >= STANDING_M_S:
            self.still_since.pop(sysid, None)
        elif now - self.still_since.setdefault(sysid, now) >= STAND_S:
            self.standing_at[sysid] = (east, north)

    def _note_arrivals(self, goals: dict[int, tuple[float, float]]) -> None:
        """When each vehicle first comes within ARRIVED_M of its goal (the simulator's truth)."""
        assert self.sim is not None
        now = asyncio.get_running_loop().time()
        for sysid, (east, north, _) in self.sim.local_positions().items():
            gx, gy = goals[sysid]
            if sysid not in self.arrived and math.hypot(east - gx, north - gy) < ARRIVED_M:
                self.arrived[sysid] = now

    async def _listen(self) -> None:
        """What the flight tells its live listeners (kept to compare with storage), from
        whichever service instance runs (a restart makes a new one)."""
        while True:
            book = self._book()
            queue = book.listen(self.flight_id)
            try:
                while self.service.app is not None and self._book() is book:
                    try:
                        async with asyncio.timeout(1.0):
                            self.live.append(await queue.get())
                    except TimeoutError:
                        continue
            finally:
                book.unlisten(self.flight_id, queue)
            await until(lambda: self.service.app is not None, 60, "the service back")

    def _book(self) -> Any:
        assert self.service.app is not None
        return self.service.app.state.services.flights.book

    async def _check_records(self) -> None:
        """The stored states follow the table, and every event told live was stored."""
        stored = await self._stored_events()
        states = [FlightState(e["data"]["state"]) for e in stored if e["kind"] == "FlightState"]
        for old, new in itertools.pairwise(states):
            if new not in FLIGHT_TRANSITIONS[old] and new != old:
                self.report.violations.append(f"state {old.value} -> {new.value} not allowed")
        kept = {json.dumps(e["data"], sort_keys=True) for e in stored}
        for message in self.live:
            if message.get("kind") in (None, "Progress") or message.get("type") != "event":
                continue
            if json.dumps(message, sort_keys=True) not in kept:
                self.report.violations.append(f"event not stored: {message.get('kind')}")

    async def _stored_events(self) -> list[dict[str, Any]]:
        events: list[dict[str, Any]] = []
        while True:
            params: dict[str, Any] = {"limit": 1000}
            if events:
                params["after"] = events[-1]["id"]
            page = (
                await self.service.client.get(f"/flights/{self.flight_id}/events", params=params)
            ).json()
            events += page
            if len(page) < 1000:
                return events

    async def _call(self, method: str, path: str, **kwargs: Any) -> httpx.Response:
        """The request, and a violation for a 5xx; an exception the app let through
        (what a server answers with a 500) is one too, and the flight goes on."""
        try:
            answer = await self.service.client.request(method, path, **kwargs)
        except Exception as exc:  # the in-process transport raises what the app raised
            answer = httpx.Response(500, text=f"{type(exc).__name__}: {exc}")
        if answer.status_code >= 500:
            self.report.violations.append(
                f"{method.upper()} {path}: {answer.status_code} {answer.text[:200]}"
            )
        return answer

    def _unhandled(self, loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        self.report.violations.append(
            f"unhandled: {context.get('message')} {context.get('exception')!r}"
        )


class _ErrorLog(logging.Handler):
    """Every ERROR the service logs is a violation (a bug caught only by a last resort)."""

    def __init__(self, report: Report) -> None:
        super().__init__(logging.ERROR)
        self.report = report

    def emit(self, record: logging.LogRecord) -> None:
        self.report.violations.append(f"logged error: {record.getMessage()[:200]}")

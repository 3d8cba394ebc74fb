"""Close approaches that timing drift is about to cause, seen before they happen.

The schedule keeper holds every pair within `pause_margin_s` of one clock, and at 1 m/s
that still lets a pair drift 1.5 m; a plan may leave less than that over 2R (the ten-UAV
crossing: 7.00 m planned for 6 m, flown at 5.89 m). Tighter margins do not help, since
every pause itself costs a vehicle about 3 s of stopping and starting.

So the guard looks `horizon_s` ahead: every vehicle goes on along its ideal flight from
the point of it where it is now (its plan time), and a pair predicted to come closer than
the plan's own closest approach less `tolerance_m` gives way: the one ahead of schedule
waits for the other. When both are on one clock the prediction is the plan itself, so a
conflict clears once the one behind has caught up. The one furthest behind never waits
(everyone else waits for it), so the fleet's clock always moves on.

The plan counts a vehicle as gone once it reaches its goal, but a real one spends its
descent there in the air (about 20 s from 10 m on ArduCopter). Until it is on the ground
it is an obstacle where it is, and a vehicle predicted to pass it closer than that
waits for it to land (the mock's ten-UAV crossing flew 5.56 m past one coming down).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from gcs.fleet.route_tracker import RouteTracker, VehicleProgress
from gcs.mission.geodesy import local_metres

CLOSING_M = 0.05
"""A pair predicted closer than the floor is a conflict only if it would also be closer
than it is now by this much: two already closer, after an upset, may still part."""


@dataclass(frozen=True)
class GuardPolicy:
    horizon_s: float = 10.0  # plan seconds looked ahead
    step_s: float = 0.2
    tolerance_m: float = 0.5  # how much drift may take from the plan's closest approach
    meet_horizon_s: float = 60.0  # plan seconds over which the keeper's pairs are chosen


@dataclass(frozen=True)
class Outlook:
    """What the guard foresees: who must wait for whom, and how close each pair comes
    over the next `meet_horizon_s` as they fly on (for the keeper's choice of pairs)."""

    gives_way: dict[str, str] = field(default_factory=dict)
    ids: tuple[str, ...] = ()
    soonest_m: NDArray[np.float64] | None = None
    must_go: frozenset[str] = frozenset()  # stopped in the way of the one furthest behind

    def meets(self, a: str, b: str, within_m: float) -> bool:
        if self.soonest_m is None or a not in self.ids or b not in self.ids:
            return False
        return bool(self.soonest_m[self.ids.index(a), self.ids.index(b)] <= within_m)


class _Path:
    """One vehicle's ideal flight: east-north metres by plan time, until it lands."""

    def __init__(self, tracker: RouteTracker, reference: tuple[float, float]) -> None:
        rows = [(0.0, *tracker.origin)]
        for visit in tracker.visits:
            rows.append((visit.arrive, visit.lat, visit.lon))
            rows.append((visit.leave, visit.lat, visit.lon))
        t, lat, lon = np.array(rows).T
        self.tracker = tracker
        self.t = t
        self.en = local_metres(lat, lon, *reference)

    def at(self, times: NDArray[np.float64]) -> NDArray[np.float64]:
        """Positions, shape (len(times), 2); NaN once the flight is over (landing)."""
        where = np.column_stack(
            [np.interp(times, self.t, self.en[:, 0]), np.interp(times, self.t, self.en[:, 1])]
        )
        where[times > self.t[-1]] = np.nan
        return where


class ConflictGuard:
    """Who must wait for whom so that drift takes no pair closer than the plan does."""

    def __init__(self, policy: GuardPolicy) -> None:
        self.policy = policy
        self._reference: tuple[float, float] | None = None
        self._paths: dict[str, _Path] = {}
        self._plan_closest: tuple[tuple[int, ...], float] | None = None

    def gives_way(
        self,
        flying: list[VehicleProgress],
        landing: list[VehicleProgress],
        trackers: dict[str, RouteTracker],
    ) -> Outlook:
        """Who must wait for whom, of the `flying` ones. A moving vehicle waits if going on
        along its plan would take it too close to one standing (stopped, or airborne and
        `landing`); of two moving ones the one waits whose standing keeps them further
        apart. A stopped one stays while going on would take it too close to another as
        that one is and, if that one stands, to it going on too (a knot of stopped ones
        that may all go on together must not wait for each other forever).

        The one furthest behind schedule never waits for another in the plan: all the
        others wait for it, so it alone brings the fleet back to one clock, and a flight
        where it waited could stand still for good. Where it would pass too close to one
        stopped for it, that one goes on (`must_go`) if it can do so safely."""
        if self._reference is None and trackers:
            self._reference = next(iter(trackers.values())).origin
        in_plan = {p.uav_id for p in flying}
        located = [p for p in [*flying, *landing] if p.lat is not None and p.lon is not None]
        located = [p for p in located if p.uav_id in in_plan or p.airborne]
        everyone = sorted(located, key=lambda p: 2 if p.uav_id not in in_plan else int(p.paused))
        moving = sum(1 for p in everyone if p.uav_id in in_plan and not p.paused)
        planned = sum(1 for p in everyone if p.uav_id in in_plan)
        if len(everyone) < 2:
            return Outlook()
        ids = [p.uav_id for p in everyone]
        lag = max(range(planned), key=lambda k: everyone[k].lag_s, default=-1)
        here, going = self._tracks(everyone, trackers)
        as_is = np.concatenate([going[:moving], here[moving:]])
        apart = _closest_approaches(here[:, :1], here[:, :1])  # now
        floor = self.plan_closest_m(trackers) - self.policy.tolerance_m
        too_close = np.minimum(floor, apart - CLOSING_M)  # unless it gets no closer
        closest = _closest_approaches(as_is, as_is)
        if_stands = _closest_approaches(here, as_is)  # [i, j]: i stands, j as it is
        if_goes = _closest_approaches(going, as_is)  # [i, j]: i goes on, j as it is
        both_go = _closest_approaches(going, going)
        waits: dict[str, str] = {}
        must_go: set[str] = set()
        for i, j in zip(*np.nonzero(np.triu(closest < too_close, k=1)), strict=True):
            if i >= moving:
                continue  # both stand: they keep their distance
            if j < moving and if_stands[j, i] > if_stands[i, j]:
                i, j = j, i
            if i == lag and j < moving:
                i, j = j, i  # the other moving one waits instead
            elif i == lag and j < planned:
                if not np.any(if_goes[j] < too_close[j]):
                    must_go.add(ids[j])  # stopped in its way, and free to go on
                continue
            waits.setdefault(ids[i], ids[j])
        for i in range(moving, planned):
            stuck = (if_goes[i] < too_close[i]) & (both_go[i] < too_close[i])
            blocked = np.nonzero(stuck)[0]
            if len(blocked) and i != lag:
                waits.setdefault(ids[i], ids[blocked[0]])
        return Outlook(waits, tuple(ids), self._soonest(everyone, trackers), frozenset(must_go))

    def _soonest(
        self, everyone: list[VehicleProgress], trackers: dict[str, RouteTracker]
    ) -> NDArray[np.float64]:
        """(n, n) closest approach over the next `meet_horizon_s`, all going on."""
        ahead = np.arange(0.0, self.policy.meet_horizon_s + 1e-9, 1.0)
        tracks = np.stack(
            [
                self._path(trackers[p.uav_id]).at(p.plan_time_s + ahead)
                if not p.landing
                else np.tile(self._here(p), (len(ahead), 1))
                for p in everyone
            ]
        )
        return _closest_approaches(tracks, tracks)

    def _tracks(
        self, everyone: list[VehicleProgress], trackers: dict[str, RouteTracker]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Each vehicle over the horizon, (n, samples, 2): standing where it is, and going
        on along its plan from where it is on it (a landing one stands either way)."""
        ahead = np.arange(0.0, self.policy.horizon_s + 1e-9, self.policy.step_s)
        here = np.stack([np.tile(self._here(p), (len(ahead), 1)) for p in everyone])
        going = here.copy()
        for k, p in enumerate(everyone):
            if not p.landing:
                going[k] = self._path(trackers[p.uav_id]).at(p.plan_time_s + ahead)
        return here, going

    def plan_closest_m(self, trackers: dict[str, RouteTracker]) -> float:
        """The closest any two vehicles come on the ideal flights, all on one clock."""
        key = tuple(id(tracker) for tracker in trackers.values())
        if self._plan_closest is None or self._plan_closest[0] != key:
            paths = [self._path(tracker) for tracker in trackers.values()]
            end = max(path.t[-1] for path in paths)
            times = np.arange(0.0, end + self.policy.step_s, self.policy.step_s)
            tracks = np.stack([path.at(times) for path in paths])
            closest = _closest_approaches(tracks, tracks)
            self._plan_closest = key, float(np.min(closest, initial=np.inf))
        return self._plan_closest[1]

    def _here(self, p: VehicleProgress) -> NDArray[np.float64]:
        assert self._reference is not None and p.lat is not None and p.lon is not None
        return local_metres(p.lat, p.lon, *self._reference)[0]

    def _path(self, tracker: RouteTracker) -> _Path:
        """Cached per tracker: a live replan gives a vehicle a new one."""
        if self._reference is None:
            self._reference = tracker.origin
        path = self._paths.get(tracker.uav_id)
        if path is None or path.tracker is not tracker:
            path = self._paths[tracker.uav_id] = _Path(tracker, self._reference)
        return path


def _closest_approaches(
    tracks: NDArray[np.float64], others: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(n, n) closest distance of track i to track j of `others`, both (n, samples, 2)
    sampled at the same moments; infinite for a pair never in the air together."""
    gaps = np.linalg.norm(tracks[:, None] - others[None, :], axis=-1)  # (n, n, samples)
    gaps = np.where(np.isnan(gaps), np.inf, gaps)
    closest = gaps.min(axis=-1)
    np.fill_diagonal(closest, np.inf)
    return closest

"""Who passes first where two UAVs' paths come close: the plan's passing order.

A plan is safe because wherever two paths come within reach of each other, one UAV has
left before the other arrives. Vehicles in the air drift off the plan's clock (they
accelerate, round corners, meet wind, take off late, are held), so a flight keeps the
plan's *order* instead of its clock, as robots executing multi-agent plans do (Hönig et
al., RA-L 2019: the action dependency graph). Each path is sampled every `step_m`; for
two samples of two UAVs closer than `reach_m + step_m`, the plan says which UAV was
there first; the other one may not come within `step_m` of its sample before the first
has gone `step_m` beyond its own. Then no two vehicles are ever closer than `reach_m`,
whatever their speeds, as long as each keeps behind its limit (`limit`).

Every such wait points forward in the plan's time (the first UAV leaves before the
second arrives), and each UAV moves forward along its path, so the waits cannot form a
cycle: no one ever waits, directly or through others, for itself. Where the plan itself
flies two UAVs within reach of each other at the same time, there is no order to keep:
that pair's reach is narrowed to what the plan keeps (`reach_m` per pair), and the
flight says so (`narrowest_margin_m`).

The rest of a flight after a live replan is not one plan's clock: kept vehicles continue
from wherever the order has them, so two of them, or a kept and a replanned one, may
seem closer than their two radii at once. There the pair is given an order all the same
(`order_together`): the one that comes first goes first, and the other waits. Such a
wait may point backwards in the plan's time, so a cycle is no longer ruled out by
construction; the flight's timing (`flight_timing`) then proves there is none: a
simulated flight in which every wait was met is an order of all the events that keeps
every wait, which a cycle would forbid (FlightStuck otherwise).

In flight, a vehicle whose stop came late can stand inside an encounter it was to wait
short of. There the encounter's waits are turned round (`swapped`), which can point
backwards too; `reach` then shows from where everyone is whether anyone would wait for
ever (`gcs.fleet.lead_taking`).
"""

from __future__ import annotations

import bisect
import dataclasses
import functools
import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from gcs.mission.geodesy import Floats

DEFAULT_STEP_M = 0.1
MOVE_EPS_M = 1e-6
ENCOUNTER_GAP_M = 1.0
"""Places a follower waits at, this far apart or more along its path, are two encounters
with its leader, not one."""


@dataclass(frozen=True)
class PlannedPath:
    """One UAV's path in metres (east, north of the grid's origin) with the plan's clock:
    it arrives at vertex k at `arrive[k]` and leaves it at `leave[k]` (later where it
    hovers), moving at a constant speed between vertices."""

    uav_id: str
    xy: Floats  # (n, 2)
    arrive: Floats  # (n,)
    leave: Floats  # (n,)
    radius_m: float
    ahead_s: float = 0.0
    """How far this clock runs ahead of the plan's: a live replan restarts a kept path
    at the replan's moment (`starting_at`)."""
    skipped_m: float = 0.0
    """How far along the UAV's earlier path this one begins: a live replan keeps the rest
    of a path (`after`)."""

    @classmethod
    def of(
        cls, uav_id: str, trajectory: Iterable[Iterable[float]], cell_m: float, radius_m: float
    ) -> PlannedPath:
        """From a plan's `[t, x, y]` rows in cells; repeated places become hovers."""
        points = np.asarray(list(trajectory), dtype=float).reshape(-1, 3)
        xy = points[:, 1:] * cell_m
        moved = np.hypot(*np.diff(xy, axis=0).T) > MOVE_EPS_M
        first = np.flatnonzero(np.concatenate([[True], moved]))
        last = np.concatenate([first[1:] - 1, [len(points) - 1]])
        return cls(uav_id, xy[first], points[first, 0], points[last, 0], radius_m)

    @cached_property
    def s(self) -> Floats:
        """Distance along the path at each vertex, metres (asked for on every tick)."""
        return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(self.xy, axis=0).T))])

    @cached_property
    def length(self) -> float:
        return float(self.s[-1])

    def after(self, s: float) -> PlannedPath:
        """What is left of the path from `s` metres along it, on the same clock."""
        k, s, t = self._clock_at(s)
        here = np.array([self.position(s)])
        rest = slice(k, None)
        return PlannedPath(
            self.uav_id,
            np.vstack([here, self.xy[rest]]),
            np.concatenate([[t], self.arrive[rest]]),
            np.concatenate([[t], self.leave[rest]]),
            self.radius_m,
            self.ahead_s,
            self.skipped_m + s,
        )

    def starting_at(self, t: float) -> PlannedPath:
        """The same path with its clock moved so that it starts at `t`."""
        by = t - float(self.arrive[0])
        return dataclasses.replace(
            self, arrive=self.arrive + by, leave=self.leave + by, ahead_s=self.ahead_s + by
        )

    def leaves(self, s: float) -> float:
        """When the plan has the UAV leave the point `s` metres along its path."""
        return self._clock_at(s)[2]

    def held(self, s: float, until: float) -> PlannedPath:
        """The same path with the UAV hovering at `s` metres along it until `until` (or
        as planned, if it leaves later anyway), and everything after it that much later."""
        k, s, t = self._clock_at(s)
        wait = until - t
        if wait <= 0:
            return self
        at_vertex = k > 0 and self.s[k - 1] == s
        xy, arrive, leave = self.xy, self.arrive.copy(), self.leave.copy()
        if not at_vertex:  # a vertex of its own, reached at t
            xy = np.insert(xy, k, self.position(s), axis=0)
            arrive, leave = np.insert(arrive, k, t), np.insert(leave, k, t)
            k += 1
        leave[k - 1] += wait
        arrive[k:] += wait
        leave[k:] += wait
        return dataclasses.replace(self, xy=xy, arrive=arrive, leave=leave)

    def _clock_at(self, s: float) -> tuple[int, float, float]:
        """(the first vertex beyond `s`, `s` kept on the path, when the UAV leaves it)."""
        along = self.s
        s = float(np.clip(s, 0.0, along[-1]))
        k = int(np.searchsorted(along, s, side="right"))
        t = float(np.interp(s, along, self.leave)) if k < len(along) else float(self.leave[-1])
        if 0 < k < len(along):  # between vertices k - 1 and k: on the clock of that leg
            f = (s - along[k - 1]) / max(along[k] - along[k - 1], 1e-12)
            t = self.leave[k - 1] + f * (self.arrive[k] - self.leave[k - 1])
        return k, s, float(t)

    def position(self, s: float) -> tuple[float, float]:
        along = self.s
        return float(np.interp(s, along, self.xy[:, 0])), float(np.interp(s, along, self.xy[:, 1]))

    def between(self, lo_m: float, hi_m: float, step_m: float = DEFAULT_STEP_M) -> Floats:
        """Points of the path from `lo_m` to `hi_m` metres along it, `step_m` apart or
        less, both ends included: (n, 2)."""
        hi_m = max(lo_m, hi_m)
        s = np.linspace(lo_m, hi_m, max(2, int(np.ceil((hi_m - lo_m) / step_m)) + 1))
        return self._points(s)

    def _points(self, s: Floats) -> Floats:
        """The points `s` metres along the path: (n, 2)."""
        along = self.s
        return np.column_stack(
            [np.interp(s, along, self.xy[:, 0]), np.interp(s, along, self.xy[:, 1])]
        )

    def samples(self, step_m: float) -> tuple[Floats, Floats, Floats, Floats]:
        """Points every `step_m` or less, and every vertex: (s, xy, when the UAV comes
        within `step_m` of the point, when it is last within `step_m` of it)."""
        along = self.s
        s_parts, t_in, t_out = [np.array([0.0])], [self.arrive[:1]], [self.leave[:1]]
        for k in range(len(along) - 1):
            length = along[k + 1] - along[k]
            count = max(1, int(np.ceil(length / step_m)))
            f = np.arange(1, count + 1) / count
            s_parts.append(along[k] + f * length)
            t = self.leave[k] + f * (self.arrive[k + 1] - self.leave[k])
            t_in.append(t)
            t_out.append(np.concatenate([t[:-1], self.leave[k + 1 : k + 2]]))
        s = np.concatenate(s_parts)
        first, last = np.concatenate(t_in), np.concatenate(t_out)
        before = np.maximum(np.searchsorted(s, s - step_m, side="right") - 1, 0)
        after = np.minimum(np.searchsorted(s, s + step_m, side="left"), len(s) - 1)
        return s, self._points(s), first[before], last[after]


@dataclass(frozen=True)
class Waits:
    """What one UAV (the follower) waits for from one other (the leader): it may reach
    `at[k]` only once the leader has passed `after[k]`, both in metres along their paths.

    Sorted by `at`; `needed` is the running maximum of `after`, so the first `at` still
    waiting for the leader is one binary search away (on plain floats: a flight and its
    timing ask every vehicle's limits many times a second). Only where `needed` rises
    can a search end, so only those places are kept for it: a pair's tens of thousands
    of sample pairs come down to a few hundred. `plan_times` are the plan's times of
    each wait's two ends (leader leaves, follower arrives): the leader's is earlier."""

    leader: str
    at: Floats
    after: Floats
    plan_times: Floats  # (k, 2): leader leaves, follower arrives
    needed: list[float] = field(init=False, repr=False)
    _at: list[float] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        needed = np.maximum.accumulate(self.after)
        rises = np.concatenate([[True], needed[1:] > needed[:-1]])
        object.__setattr__(self, "needed", needed[rises].tolist())
        object.__setattr__(self, "_at", np.asarray(self.at)[rises].tolist())

    def limit(self, leader_at: float) -> float:
        """How far along its path the follower may go while the leader is at `leader_at`."""
        k = bisect.bisect_left(self.needed, leader_at)
        return self._at[k] if k < len(self._at) else math.inf


@dataclass(frozen=True)
class Encounter:
    """Where a follower waits for a leader: from `first_m` to `last_m` along its path,
    until the leader is `cleared_m` along its own."""

    leader: str
    first_m: float
    last_m: float
    cleared_m: float


@dataclass(frozen=True)
class Limit:
    """How far a vehicle may go now, and who stops it there (None: nobody)."""

    at_m: float
    leader: str | None


@dataclass
class PassingOrder:
    """Every UAV's waits, by follower, and each pair's reach (their protected distance)."""

    waits: dict[str, list[Waits]]
    reach_m: dict[tuple[str, str], float]
    step_m: float

    @classmethod
    def derive(
        cls,
        paths: Iterable[PlannedPath],
        margin_m: float,
        step_m: float = DEFAULT_STEP_M,
        order_together: bool = False,
        committed_m: Mapping[str, float] | None = None,
        like: tuple[PassingOrder, Mapping[str, PlannedPath]] | None = None,
    ) -> PassingOrder:
        """The order of the plan's close encounters, keeping every pair `2R + margin_m`
        apart where the plan leaves room for it (and what the plan keeps where not,
        unless `order_together`: see above). A UAV that cannot stop within
        `committed_m` of its path's start (one flying on at a live replan) leads every
        encounter it meets within that, whatever the plan's times: told to wait there, it
        would stop past the place (real ArduCopter: 4.75 m from the vehicle it was to let
        by, with 2R 6 m). So does, with `order_together`, one whose path begins inside
        an encounter (`_bound`). Where both are, the plan's times decide.

        `like` is an order derived the same way from paths of which some are these very
        objects: a pair of two such is taken from it, not derived again (holding one of
        twelve landers short changes 11 of 66 pairs)."""
        committed = committed_m or {}
        given = {p.uav_id: p for p in paths}
        waits: dict[str, list[Waits]] = {uav: [] for uav in given}
        reach: dict[tuple[str, str], float] = {}
        known, known_paths = like if like is not None else (None, {})
        sampled = functools.cache(lambda uav: given[uav].samples(step_m))
        for a, b in itertools.combinations(sorted(given), 2):
            pa, pb = given[a], given[b]
            if known is not None and known_paths.get(a) is pa and known_paths.get(b) is pb:
                reach[(a, b)] = known.reach_m[(a, b)]
                for follower, leader in ((a, b), (b, a)):
                    waits[follower] += [w for w in known.waits[follower] if w.leader == leader]
                continue
            wanted = pa.radius_m + pb.radius_m + margin_m
            within = pa.radius_m + pb.radius_m if order_together else 0.0
            reach[(a, b)], found = _pair_waits(
                sampled(a), sampled(b), wanted, step_m, within,
                (committed.get(a, 0.0), committed.get(b, 0.0)),
            )  # fmt: skip
            for follower, leader, wait in ((b, a, found[0]), (a, b, found[1])):
                if wait is not None:
                    waits[follower].append(Waits(leader, *wait))
        return cls(waits, reach, step_m)

    def limit(self, follower: str, progress: Mapping[str, float]) -> Limit:
        """How far `follower` may go while the others are at `progress` (metres along
        their paths; a UAV not in `progress` is taken as not yet started)."""
        best = Limit(np.inf, None)
        for wait in self.waits.get(follower, ()):
            at = wait.limit(progress.get(wait.leader, 0.0))
            if at < best.at_m:
                best = Limit(at, wait.leader)
        return best

    def swapped(self, follower: str, leader: str, limit_m: float) -> PassingOrder | None:
        """The same order, but with `follower` leading `leader` through the encounter in
        which it was to wait at `limit_m` (None if it waits there for nobody): it stopped
        past that place, inside the encounter, and the leader would pass it where it
        stands (fuzzed flight 6698: a pause lost four times running, 1.5 m past its
        limit, passed 5.43 m away with 2R 6 m). Each wait of the encounter is turned
        round: the sample pair that kept the follower short of `at` until the leader
        was past `after` now keeps the leader short of its own sample until the follower
        is past its. Other encounters of the pair keep their order."""
        wait = next((w for w in self.waits.get(follower, ()) if w.leader == leader), None)
        if wait is None:
            return None
        at = np.asarray(wait.at)
        starts = _encounter_starts(at)
        first = starts[max(0, int(np.searchsorted(at[starts], limit_m, side="right")) - 1)]
        last = next((k for k in starts if k > first), len(at))
        turned = slice(first, last)
        kept = np.r_[0:first, last : len(at)]
        two_steps = 2 * self.step_m
        waits = {uav: list(ws) for uav, ws in self.waits.items()}
        waits[follower] = [w for w in waits[follower] if w is not wait]
        if len(kept):
            waits[follower].append(Waits(leader, at[kept], wait.after[kept], wait.plan_times[kept]))
        reverse = [w for w in waits[leader] if w.leader == follower]
        waits[leader] = [w for w in waits[leader] if w.leader != follower]
        new_at = np.concatenate([wait.after[turned] - two_steps, *(w.at for w in reverse)])
        new_after = np.concatenate([at[turned] + two_steps, *(w.after for w in reverse)])
        times = np.vstack([wait.plan_times[turned][:, ::-1], *(w.plan_times for w in reverse)])
        order = np.lexsort((new_after, new_at))
        waits[leader].append(Waits(follower, new_at[order], new_after[order], times[order]))
        return PassingOrder(waits, self.reach_m, self.step_m)

    def encounters(self, follower: str) -> list[Encounter]:
        """Each encounter in which `follower` waits, in the order of its waits."""
        found = []
        for wait in self.waits.get(follower, ()):
            at, after = np.asarray(wait.at), np.asarray(wait.after)
            starts = _encounter_starts(at)
            for a, b in zip(starts, np.r_[starts[1:], len(at)], strict=True):
                cleared = float(after[a:b].max())
                found.append(Encounter(wait.leader, float(at[a]), float(at[b - 1]), cleared))
        return found

    def reach(self, progress: Mapping[str, float], ends: Mapping[str, float]) -> dict[str, float]:
        """How far each UAV can get from `progress` under this order, whoever waits for
        whom (`inf`: to its end, where it lands and is out of the way). Every limit only
        rises as the leaders go on, so letting each UAV go to its limit until none can go
        further reaches every place the order lets anyone reach: a UAV short of its end
        then waits, directly or through others, for itself."""
        at = {uav: math.inf if s >= ends[uav] else s for uav, s in progress.items()}
        moving = True
        while moving:
            moving = False
            for uav, s in at.items():
                if s == math.inf:
                    continue
                to = min(self.limit(uav, at).at_m, ends[uav])
                if to > s + MOVE_EPS_M:
                    at[uav], moving = (math.inf if to >= ends[uav] else to), True
        return at

    def narrowest_margin_m(self, radii: Mapping[str, float]) -> float:
        """The smallest reach beyond 2R over all pairs: what the order keeps in hand."""
        return min((r - radii[a] - radii[b] for (a, b), r in self.reach_m.items()), default=np.inf)

    def release(self, leader: str) -> None:
        """`leader` is out of everyone's way for good (down on the ground)."""
        for follower, waits in self.waits.items():
            self.waits[follower] = [w for w in waits if w.leader != leader]


Samples = tuple[Floats, Floats, Floats, Floats]
Found = tuple[Floats, Floats, Floats] | None


def _pair_waits(
    a: Samples,
    b: Samples,
    wanted_m: float,
    step_m: float,
    order_within_m: float,
    committed_m: tuple[float, float] = (0.0, 0.0),
) -> tuple[float, tuple[Found, Found]]:
    """The reach kept between two sampled paths, and the waits of b for a and of a for b.

    A wait keeps the follower `step_m` short of its sample until the leader is `step_m`
    beyond its own: positions between samples are then covered too. Where the plan has
    them within reach at once, and anywhere closer than `order_within_m`, the one that
    comes there first leads wherever they come within reach (a lead taken in part would
    have each wait for the other); otherwise the reach is what the plan keeps."""
    s_a, xy_a, in_a, out_a = a
    s_b, xy_b, in_b, out_b = b
    close = cKDTree(xy_a).sparse_distance_matrix(
        cKDTree(xy_b), wanted_m + step_m, output_type="ndarray"
    )
    i, j, d = close["i"], close["j"], close["v"]
    a_first = out_a[i] <= in_b[j]
    b_first = ~a_first & (out_b[j] <= in_a[i])
    together = ~(a_first | b_first)
    reach = wanted_m
    a_bound, b_bound = _bound(
        s_a[i].min() - step_m if len(i) else math.inf,
        s_b[j].min() - step_m if len(j) else math.inf,
        committed_m,
        inside_leads=order_within_m > 0.0,
    )
    if a_bound != b_bound:
        a_first = np.full(len(d), a_bound)
        b_first = ~a_first
    elif (d[together] < order_within_m).any():  # one leads in all of the pair's encounter
        a_first = np.full(len(d), in_a[i[together]].min() <= in_b[j[together]].min())
        b_first = ~a_first
    elif together.any():  # the plan flies them this close at once: keep what it keeps
        reach = float(d[together].min()) - step_m
        keep = d < reach + step_m
        i, j, a_first, b_first = i[keep], j[keep], a_first[keep], b_first[keep]
    b_waits = _waits(s_b[j[a_first]], s_a[i[a_first]], out_a[i[a_first]], in_b[j[a_first]], step_m)
    a_waits = _waits(s_a[i[b_first]], s_b[j[b_first]], out_b[j[b_first]], in_a[i[b_first]], step_m)
    return reach, (b_waits, a_waits)


def _bound(
    wait_a: float, wait_b: float, committed_m: tuple[float, float], inside_leads: bool
) -> tuple[bool, bool]:
    """Which of the two must lead their whole encounter, whatever the plan's times: one
    already in it where the rest of a flight starts (`inside_leads`; it cannot wait
    short of it, and the other would pass it where it stands: fuzzed flight 4494,
    4.10 m), else one that would reach it before it could stop. Where both are in it,
    neither is bound: they are a pair in reach at once."""
    inside = (wait_a < 0.0, wait_b < 0.0)
    if any(inside):
        return inside if inside_leads and not all(inside) else (False, False)
    return wait_a < committed_m[0], wait_b < committed_m[1]


def _encounter_starts(at: Floats) -> Floats:
    """Where each encounter of a wait begins (indices into its sorted `at`): the samples
    of one are less than ENCOUNTER_GAP_M apart."""
    return np.concatenate([[0], np.flatnonzero(np.diff(at) > ENCOUNTER_GAP_M) + 1])


def _waits(at: Floats, after: Floats, leaves: Floats, arrives: Floats, step_m: float) -> Found:
    if len(at) == 0:
        return None
    order = np.lexsort((after, at))
    return (
        at[order] - step_m,
        after[order] + step_m,
        np.column_stack([leaves[order], arrives[order]]),
    )

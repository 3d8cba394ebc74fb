"""The memo of failed space-time searches (`space_time.Failure`, 6ad94a5): a search the
memo skips would fail again, the same way (the same move origins tested, against the
same flights); and a change it could meet (a flight tested against, a flight now near
an origin tested, another horizon, other limits, radius or speed, grid) runs it again."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from numpy.typing import NDArray

from planner.check.safety import closest_approach
from planner.model.scenario import UAVSpec
from planner.model.trajectory import Trajectory
from planner.search import space_time
from planner.search.sipp import Mover
from planner.search.space_time import Failure, SearchLimits

END = 10.0  # every flight below ends then: the search's horizon and buckets stay the same
SPEC = UAVSpec(id="u", start=(0, 0), goal=(13, 13))
TIGHT = SearchLimits(max_expansions=12)  # far too few to cross the grid: a sure failure


def _hovering(points: list[tuple[float, float]], speed: float = 1.0) -> Trajectory:
    """Through `points`, then hovering at the last until END."""
    flight = Trajectory.from_waypoints(points, speed)
    assert flight.end_time < END
    return Trajectory.from_waypoints(
        points, speed, [0.0] * (len(points) - 1) + [END - flight.end_time]
    )


# Crosses the UAV's first cells (every early move is tested against it).
NEAR = Mover(_hovering([(3.0, 0.0), (0.0, 3.0), (0.0, 6.0)]), 0.3, 1.0)
# Keeps to the far corner, where the few expansions never come.
FAR = Mover(_hovering([(13.0, 0.0), (10.0, 0.0)]), 0.3, 1.0)


@pytest.fixture
def runs(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """How many searches really ran (the memo's skips return None without running)."""
    count = [0]
    real = space_time._IndexedSearch.run

    def counted(self: space_time._IndexedSearch) -> list[tuple[float, int, int]] | str:
        count[0] += 1
        return real(self)

    monkeypatch.setattr(space_time._IndexedSearch, "run", counted)
    yield count


def _failed(
    free: NDArray[np.bool_], others: list[Mover], limits: SearchLimits = TIGHT
) -> dict[str, Failure]:
    failures: dict[str, Failure] = {}
    assert space_time.search(SPEC, free, others, limits, failures=failures) is None
    assert set(failures) == {SPEC.id}
    return failures


def _same_failure(a: Failure, b: Failure) -> None:
    assert np.array_equal(a.origins, b.origins)
    assert a.touched == b.touched


def test_a_failure_is_remembered_with_the_flights_it_met_and_where_it_looked() -> None:
    free = np.ones((14, 14), dtype=bool)
    known = _failed(free, [NEAR, FAR])[SPEC.id]
    assert known.touched == {0}  # NEAR only
    assert len(known.origins) > 0
    # The few expansions head for the goal: FAR's corner, x in [10, 13] and y = 0, stays
    # further than any index reach (about 3.5 cells) from every origin tested.
    assert np.all(known.origins[:, 1] <= 10.0)
    assert np.hypot(known.origins[:, 1] - 10.0, known.origins[:, 2]).min() > 5.0


def test_a_skipped_search_fails_again_as_it_failed(runs: list[int]) -> None:
    free = np.ones((14, 14), dtype=bool)
    failures = _failed(free, [NEAR, FAR])
    before = failures[SPEC.id]
    # FAR moves, still far from every origin tested and ending at END: the memo skips.
    moved = Mover(_hovering([(13.0, 2.0), (12.0, 1.0), (13.0, 0.0)]), 0.3, 1.0)
    others = [NEAR, moved]
    runs[0] = 0
    assert space_time.search(SPEC, free, others, TIGHT, failures=failures) is None
    assert runs[0] == 0, "the memo should have skipped this search"
    assert failures[SPEC.id] is before
    # Run anyway: it fails, from the same origins, against the same flights.
    fresh: dict[str, Failure] = {}
    assert space_time.search(SPEC, free, others, TIGHT, failures=fresh) is None
    assert runs[0] == 1
    _same_failure(fresh[SPEC.id], before)
    # The same flights again (new objects, same points): skipped too.
    copies = [Mover(Trajectory(o.trajectory.points.copy()), o.radius, o.speed) for o in others]
    assert space_time.search(SPEC, free, copies, TIGHT, failures=failures) is None
    assert runs[0] == 1


def _skipped(failures: dict[str, Failure], free: NDArray[np.bool_], others: list[Mover]) -> bool:
    """Whether the memo skips this search (asked as `search` asks it, without running)."""
    spied: list[bool] = []
    real = Failure.fails_again

    def spy(self: Failure, run: space_time._IndexedSearch, movers: list[Mover]) -> bool:
        spied.append(real(self, run, movers))
        return spied[-1]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(Failure, "fails_again", spy)
        patch.setattr(space_time._IndexedSearch, "run", lambda self: "not run")
        space_time.search(SPEC, free, others, TIGHT, failures=dict(failures))
    assert len(spied) == 1
    return spied[0]


def test_random_changes_the_memo_skips_all_fail_again() -> None:
    """Random grids, flights and one changed flight each: every search the memo skips,
    run anyway, fails from the same origins against the same flights."""
    skipped = rerun = 0
    for seed in range(30):
        rng = np.random.default_rng(seed)
        free = rng.random((14, 14)) >= 0.15
        free[0, 0] = free[13, 13] = True
        others = [_random_mover(rng) for _ in range(5)]
        failures: dict[str, Failure] = {}
        if space_time.search(SPEC, free, others, TIGHT, failures=failures) is not None:
            continue
        before = failures[SPEC.id]
        for _ in range(4):
            changed = list(others)
            changed[int(rng.integers(len(others)))] = _random_mover(rng)
            if _skipped(failures, free, changed):
                skipped += 1
                fresh: dict[str, Failure] = {}
                assert space_time.search(SPEC, free, changed, TIGHT, failures=fresh) is None
                _same_failure(fresh[SPEC.id], before)
            else:
                rerun += 1
    assert skipped >= 10 and rerun >= 10  # both sides of the memo were exercised


def _random_mover(rng: np.random.Generator) -> Mover:
    points = [(float(x), float(y)) for x, y in rng.uniform(0.0, 13.0, (2, 2))]
    return Mover(_hovering(points, 2.0), 0.3, 2.0)


# -- what runs it again ---------------------------------------------------------------


def test_a_change_to_a_flight_it_was_tested_against_runs_it_again(runs: list[int]) -> None:
    free = np.ones((14, 14), dtype=bool)
    failures = _failed(free, [NEAR, FAR])
    nudged = Mover(_hovering([(3.0, 0.0), (0.0, 3.0), (0.0, 6.5)]), 0.3, 1.0)
    assert not _skipped(failures, free, [nudged, FAR])
    runs[0] = 0
    assert space_time.search(SPEC, free, [nudged, FAR], TIGHT, failures=failures) is None
    assert runs[0] == 1


def test_a_flight_coming_near_an_origin_tested_runs_it_again(runs: list[int]) -> None:
    free = np.ones((14, 14), dtype=bool)
    failures = _failed(free, [NEAR, FAR])
    assert 1 not in failures[SPEC.id].touched
    # FAR, never tested against, now flies past the start at the start.
    passing = Mover(_hovering([(2.0, 2.0), (9.0, 0.0), (10.0, 0.0)]), 0.3, 1.0)
    assert not _skipped(failures, free, [NEAR, passing])
    runs[0] = 0
    space_time.search(SPEC, free, [NEAR, passing], TIGHT, failures=failures)
    assert runs[0] == 1
    assert 1 in failures[SPEC.id].touched  # and it met it this time


def test_a_later_flight_a_new_horizon_runs_it_again() -> None:
    free = np.ones((14, 14), dtype=bool)
    failures = _failed(free, [NEAR, FAR])
    # Far away still, but ending later: another horizon and more buckets.
    later = Mover(Trajectory.from_waypoints([(13.0, 0.0), (10.0, 0.0)], 1.0, [0.0, END]), 0.3, 1.0)
    assert later.trajectory.end_time > END
    assert not _skipped(failures, free, [NEAR, later])


def test_other_limits_radius_speed_or_grid_run_it_again() -> None:
    free = np.ones((14, 14), dtype=bool)
    failures = _failed(free, [NEAR, FAR])
    assert _skipped(failures, free, [NEAR, FAR])  # nothing changed: skipped
    # More expansions: run again, and this time it finds its way.
    more: dict[str, Failure] = dict(failures)
    found = space_time.search(SPEC, free, [NEAR, FAR], SearchLimits(), failures=more)
    assert found is not None and np.allclose(found.end, (13, 13))
    assert SPEC.id not in more  # a success forgets the failure
    # FAR's radius or speed, untouched flight though it is.
    assert not _skipped(failures, free, [NEAR, Mover(FAR.trajectory, 0.35, 1.0)])
    assert not _skipped(failures, free, [NEAR, Mover(FAR.trajectory, 0.3, 2.0)])
    # Another grid (the memo knows a grid by identity), or one flight fewer.
    assert not _skipped(failures, free.copy(), [NEAR, FAR])
    assert not _skipped(failures, free, [NEAR])


def test_a_flight_that_moves_out_of_the_way_lets_the_search_succeed(runs: list[int]) -> None:
    """A head-on meeting in a one-cell corridor fails; the oncoming flight moved (one
    it was tested against) the search runs again and finds the way, as it must."""
    free = np.zeros((9, 3), dtype=bool)
    free[:, 1] = True
    spec = UAVSpec(id="c", start=(0, 1), goal=(8, 1))
    oncoming = Mover(Trajectory.from_waypoints([(8, 1), (0, 1)], 1.0, [0.0, 30.0]), 0.3, 1.0)
    failures: dict[str, Failure] = {}
    assert space_time.search(spec, free, [oncoming], failures=failures) is None
    assert failures[spec.id].touched == {0}
    # The same meeting: skipped.
    runs[0] = 0
    assert space_time.search(spec, free, [oncoming], failures=failures) is None
    assert runs[0] == 0
    # It now leaves the corridor at once, sideways, and hovers out of it.
    late = Mover(Trajectory.from_waypoints([(8, 1), (8, -5)], 1.0, [0.0, 32.0]), 0.3, 1.0)
    assert late.trajectory.end_time == oncoming.trajectory.end_time
    flight = space_time.search(spec, free, [late], failures=failures)
    assert runs[0] == 1
    assert flight is not None and np.allclose(flight.end, (8, 1))
    assert closest_approach(flight, late.trajectory)[0] >= 0.6 - 1e-9

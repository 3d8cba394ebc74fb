"""Taking up a vehicle already on its way (a flight followed again after a restart or a
takeover): where it is along its path, and on its plan's clock."""

from __future__ import annotations

import numpy as np
import pytest

from gcs.fleet.path_progress import PathProgress
from gcs.fleet.route_tracker import RouteTracker
from gcs.mavlink.vehicle_state import LandedState, Position, VehicleState
from gcs.mission.build import Visit
from gcs.mission.geodesy import GridFrame
from gcs.mission.passing_order import PlannedPath

FRAME = GridFrame(-35.3632, 149.1652, 584.0, 10.0)
U_TURN = PlannedPath(  # east 100 m, north 20 m, back west 100 m: the two passes 20 m apart
    "uav1",
    np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 20.0], [0.0, 20.0]]),
    np.array([0.0, 10.0, 12.0, 22.0]),
    np.array([0.0, 10.0, 12.0, 22.0]),
    3.0,
)


def flying_at(
    east_m: float, north_m: float, *, seq: int = 1, boot_ms: int = 90_000
) -> VehicleState:
    lat, lon = FRAME.to_geodetic(east_m / FRAME.cell_size_m, north_m / FRAME.cell_size_m)
    state = VehicleState(sysid=1, autopilot=3, time_boot_ms=boot_ms, link_up=True)
    state.position = Position(float(lat), float(lon), 20.0, 604.0, time_boot_ms=boot_ms)
    state.armed, state.landed_state, state.mission_seq = True, LandedState.IN_AIR, seq
    state.velocity_n_e_m_s = (0.0, -5.0)  # west, as on the way back
    return state


@pytest.mark.parametrize(("lo", "hi", "expected"), [(0.0, 100.0, 50.0), (120.0, 220.0, 170.0)])
def test_a_vehicle_between_two_passes_is_placed_on_the_pass_its_items_say(
    lo: float, hi: float, expected: float
) -> None:
    """Halfway between the two passes the nearest point is on either: the items the
    vehicle has passed and flies to decide which."""
    progress = PathProgress(U_TURN, FRAME)
    progress.find(flying_at(50.0, 10.0), lo, hi)
    assert progress.s == pytest.approx(expected, abs=0.1)


def test_a_vehicle_found_on_its_way_goes_on_from_there() -> None:
    progress = PathProgress(U_TURN, FRAME)
    progress.find(flying_at(60.0, 19.0), 120.0, 220.0)
    assert progress.s == pytest.approx(160.0, abs=0.1)
    assert progress.update(flying_at(55.0, 20.0, boot_ms=91_000))
    assert progress.s == pytest.approx(165.0, abs=0.1)


def test_a_vehicle_that_sped_up_and_braked_while_unheard_is_found_where_it_stopped() -> None:
    """Its speeds either side of the silence say nothing of how far it flew meanwhile:
    fuzzed flight 1529 with a link drop: uav4 was heard creeping from its start, flew
    8 m unheard and braked (its GCS failsafe), and was looked for within 6 m of its
    start from then on, taken to stand there while it flew into another's way."""
    progress = PathProgress(U_TURN, FRAME, top_speed_m_s=10.0)
    creeping = flying_at(0.1, 0.0, boot_ms=90_000)
    creeping.velocity_n_e_m_s = (0.0, 0.3)
    assert progress.update(creeping)
    braked = flying_at(30.0, 0.0, boot_ms=95_000)
    braked.velocity_n_e_m_s = (0.0, 0.0)
    assert progress.update(braked)
    assert progress.s == pytest.approx(30.0, abs=0.1)


VISITS = [
    Visit(seq=2, arrive=10.0, leave=10.0, lat=0.0, lon=0.0),
    Visit(seq=3, arrive=12.0, leave=12.0, lat=0.0, lon=0.0),
    Visit(seq=4, arrive=22.0, leave=22.0, lat=0.0, lon=0.0, lands=True),
]


def _visits() -> list[Visit]:
    """The U-turn's corners and its end, where the path puts them."""
    corners = [(100.0, 0.0), (100.0, 20.0), (0.0, 20.0)]
    visits = []
    for visit, (east, north) in zip(VISITS, corners, strict=True):
        lat, lon = FRAME.to_geodetic(east / FRAME.cell_size_m, north / FRAME.cell_size_m)
        visits.append(
            Visit(visit.seq, visit.arrive, visit.leave, float(lat), float(lon), visit.lands)
        )
    return visits


def test_a_tracker_found_on_the_way_has_passed_the_items_before_its_current_one() -> None:
    origin = FRAME.to_geodetic(0.0, 0.0)
    tracker = RouteTracker("uav1", _visits(), (float(origin[0]), float(origin[1])))
    state = flying_at(50.0, 20.0, seq=4)  # halfway down the last leg
    tracker.find(state)
    assert tracker.newly_passed(state) == []  # nothing is reported again
    passed, ahead = tracker.places(state)
    assert passed is not None and passed.seq == 3 and ahead is not None and ahead.seq == 4
    assert tracker.plan_time(state) == pytest.approx(17.0, abs=0.05)
    assert tracker.clock(state) == pytest.approx(17.0, abs=0.05)  # no lag known
    assert tracker.passed_at(0) == 10.0 and tracker.passed_at(1) == 12.0


def test_after_a_replan_a_vehicle_that_flew_on_from_the_new_paths_start_is_found() -> None:
    """The replanned path starts where the vehicle was when the replan began; it flew on
    5 m while the missions went up. Looked for only a few metres on, it was never found
    again (fuzzed flight 3034, where the order then held it at its start while it flew)."""
    progress = PathProgress(U_TURN, FRAME)
    progress.update(flying_at(30.0, 0.0))
    progress.restart(U_TURN.after(30.0), flying_at(35.0, 0.0, boot_ms=93_000), within_m=75.0)
    assert progress.s == pytest.approx(5.0, abs=0.1)
    assert progress.update(flying_at(36.0, 0.0, boot_ms=93_200))
    assert progress.s == pytest.approx(6.0, abs=0.1)


def test_after_a_replan_a_kept_vehicle_goes_on_from_where_it_was_on_the_rest() -> None:
    """A kept vehicle's path is the rest of its old one: the vehicle stays where it was,
    counted from where the rest begins. Found anew on a path that comes back over itself,
    it was put on the wrong pass and left there while it flew on (fuzzed flight 3499)."""
    progress = PathProgress(U_TURN, FRAME)
    progress.find(flying_at(60.0, 19.0), 120.0, 220.0)  # on the way back, 160 m along
    rest = U_TURN.after(100.0).starting_at(40.0)  # the replan kept it from 100 m on
    assert rest.skipped_m == pytest.approx(100.0)
    progress.carry_on(rest)
    assert progress.s == pytest.approx(60.0, abs=0.1)
    assert progress.update(flying_at(55.0, 20.0, boot_ms=91_000))  # west, on the way back
    assert progress.s == pytest.approx(65.0, abs=0.1)

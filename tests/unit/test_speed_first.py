"""An approach from a stop where the room is short gets its speed before it sets off
(`Gatekeeper._speed_first`): sent on the other way round, a vehicle whose link falls
silent between the two commands flies its item afresh at its mission's speed until its
own failsafe brakes it (fuzzed flight 20276)."""

from __future__ import annotations

import pytest

from gcs.fleet.gatekeeper import STOPPED_M_S, GateChange, Gatekeeper
from gcs.fleet.path_progress import PathProgress
from gcs.mission.geodesy import GridFrame
from gcs.mission.motion import CopterLimits, Gate
from gcs.mission.passing_order import PassingOrder, PlannedPath
from sitl_mock.codec import mavlink
from tests.unit.sitl_mock.test_speed_fidelity import (
    ACCEPTED,
    PAUSE,
    STILL_M_S,
    Flight,
    halt,
    speed_item,
    takeoff_item,
    waypoint,
)

FRAME = GridFrame(-35.3632, 149.1652, 584.0, 1.0)
LIMITS = CopterLimits(speed_m_s=5.0)


@pytest.mark.parametrize(("cruise", "silent_s"), [(5.0, 2.0), (10.0, 2.0), (10.0, 4.0)])
def test_an_item_flown_afresh_unheard_runs_no_further_than_reckoned(
    cruise: float, silent_s: float
) -> None:
    """The mock, paused and standing on a leg at `cruise` with its GCS failsafe set to
    brake after `silent_s`: its item made current, then nothing heard. It runs on until
    its failsafe brakes it, no further than `CopterLimits.unheard_run_m` (mock: 3.38 m
    and 3.49 m after 2 s, 19.6 m after 4 s, as at speed-up 2; reckoned 5.8, 5.8 and
    26.2 m; fuzzed flight 20276 ran 4.4 m)."""
    flight = Flight(mission=[takeoff_item(), speed_item(cruise), waypoint(0.0, 300.0)])
    for name, value in (("FS_GCS_ENABLE", 7.0), ("FS_GCS_TIMEOUT", silent_s)):
        flight.deliver(
            mavlink.MAVLink_param_set_message(
                1, 1, name.encode(), value, mavlink.MAV_PARAM_TYPE_REAL32
            )
        )
    flight.hover()
    assert flight.mode("AUTO") == ACCEPTED
    flight.fly_until(lambda s: s.speed >= cruise / 2, limit_s=30.0)
    halt(flight, lambda: flight.command(mavlink.MAV_CMD_DO_PAUSE_CONTINUE, PAUSE))
    start = flight.now
    flight.deliver(mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))  # its last
    flight.deliver(mavlink.MAVLink_mission_set_current_message(1, 1, 3))
    went = flight.fly(silent_s)
    went += flight.fly_until(lambda s: s.speed < STILL_M_S, limit_s=30.0)
    run = went[-1].north - start.north
    reckoned = CopterLimits(speed_m_s=cruise).unheard_run_m(silent_s)
    assert went[-1].mode == "BRAKE"
    assert 0.5 * reckoned <= run <= reckoned


A = PlannedPath.of("a", [[0, -20, 60], [4, 20, 60]], cell_m=1.0, radius_m=3.0)
B = PlannedPath.of("b", [[0, 0, 0], [3, 0, 0], [15, 0, 120]], cell_m=1.0, radius_m=3.0)
"""b, northward, waits for a to cross its way about 53 m on."""


def _send_on(gap_m: float, speed: float, silent_s: float | None) -> list[GateChange]:
    """b stopped `gap_m` short of its limit at `speed`, its failsafe braking after
    `silent_s` of silence (None: not known): what the gatekeeper does with it."""
    order = PassingOrder.derive([A, B], margin_m=0.5)
    keeper = Gatekeeper(order, {"a": LIMITS, "b": LIMITS})
    if silent_s is not None:
        keeper.silent_s["b"] = silent_s
    keeper.gates["b"] = Gate.STOP
    progress = {"a": PathProgress(A, FRAME), "b": PathProgress(B, FRAME)}
    b = progress["b"]
    b.s, b.speed = order.limit("b", {"a": 0.0, "b": 0.0}).at_m - gap_m, speed
    return keeper.decide(progress, ["b"])


@pytest.mark.parametrize(
    ("gap_m", "silent_s", "speed_first"),
    [(8.0, 2.0, False), (8.0, 4.0, True), (22.0, 4.0, False), (22.0, None, True)],
)
def test_an_approach_short_of_an_unheard_run_is_given_its_speed_first(
    gap_m: float, silent_s: float | None, speed_first: bool
) -> None:
    """At 5 m/s an unheard run is 5.8 m after 2 s of silence and 21.6 m after 4 s (a
    vehicle at speed-up 2); for ever where its failsafe is not known."""
    [change] = _send_on(gap_m, 0.0, silent_s)
    assert change.gate == Gate.CREEP and change.speed_m_s is not None
    assert change.speed_first is speed_first


def test_one_given_its_speed_first_is_sent_on_only_once_it_stands() -> None:
    """ArduCopter starts an item made current at where a moving vehicle would stop (SITL,
    still at 0.5 m/s: 1.7 m/s forward, then 0.5 m back): a vehicle still moving is sent
    on only the usual way, where that surge is caught as it comes."""
    moving = 0.3
    assert moving >= STOPPED_M_S
    [held] = _send_on(8.0, moving, 4.0)
    assert held.gate == Gate.STOP and not held.speed_first
    [change] = _send_on(8.0, moving, 2.0)
    assert change.gate == Gate.CREEP and not change.speed_first

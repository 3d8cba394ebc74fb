"""Who the passing order lets go at the start: a mission started from a hover speeds up
at once, so a vehicle whose limit is close ahead is held, not sent on and paused."""

from __future__ import annotations

import pytest

from gcs.fleet.gatekeeper import Gatekeeper
from gcs.fleet.path_progress import PathProgress
from gcs.mission.geodesy import GridFrame
from gcs.mission.motion import CopterLimits, Gate
from gcs.mission.passing_order import PassingOrder, PlannedPath

FRAME = GridFrame(-35.3632, 149.1652, 584.0, 1.0)
LIMITS = CopterLimits(speed_m_s=10.0)
# "a" crosses 8 m ahead of "b"'s start at t = 1 s; "b" leaves at t = 3 s.
A = PlannedPath.of("a", [[0, 0, 8], [2, 20, 8]], cell_m=1.0, radius_m=3.0)
B = PlannedPath.of("b", [[0, 10, 0], [3, 10, 0], [5, 10, 20]], cell_m=1.0, radius_m=3.0)


@pytest.mark.parametrize("starting", [True, False])
def test_a_vehicle_whose_limit_is_close_ahead_is_held_at_the_start(starting: bool) -> None:
    """b may not come within reach of a's crossing before a has passed: its limit is
    about 1.4 m ahead. A mission started from a hover speeds up at once (fuzzed flight
    3585: let go, paused at once, it went on 5.6 m), and so does one hovering below its
    track's speed anywhere else (a waypoint's hold ends, a corner's steady speed: fuzzed
    flight 11574): held either way."""
    order = PassingOrder.derive([A, B], margin_m=0.5)
    keeper = Gatekeeper(order, {"a": LIMITS, "b": LIMITS})
    progress = {"a": PathProgress(A, FRAME), "b": PathProgress(B, FRAME)}
    gap = order.limit("b", {"a": 0.0, "b": 0.0}).at_m
    assert 0.5 < gap < 3.0
    changes = keeper.decide(progress, ["a", "b"], starting=starting)
    assert [c.uav_id for c in changes] == ["b"]
    assert keeper.gates == {"a": Gate.GO, "b": Gate.STOP}

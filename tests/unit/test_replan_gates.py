"""The passing order while a live replan is uploaded: the vehicles it keeps on their paths
fly on, and keep the order it brings as well as today's."""

from __future__ import annotations

from gcs.fleet.gatekeeper import Gatekeeper
from gcs.fleet.path_progress import PathProgress
from gcs.mission.geodesy import GridFrame
from gcs.mission.motion import CopterLimits, Gate
from gcs.mission.passing_order import PassingOrder, PlannedPath
from tests.unit.test_passing_order import _crossing_pair

FRAME = GridFrame(-35.3632, 149.1652, 584.0, 1.0)
LIMITS = {"a": CopterLimits(speed_m_s=5.0), "b": CopterLimits(speed_m_s=5.0)}
MARGIN_M = 0.5


def _flying(paths: dict[str, PlannedPath], s: dict[str, float]) -> dict[str, PathProgress]:
    progress = {}
    for uav, path in paths.items():
        progress[uav] = PathProgress(path, FRAME)
        progress[uav].s, progress[uav].speed = s[uav], 5.0
    return progress


def test_a_kept_vehicle_waits_where_the_coming_order_says_until_it_comes() -> None:
    """Today a crosses first; the replan, checked when both were 10 m along, has b cross
    first. a, flying on toward the crossing meanwhile, is stopped short of it (fuzzed
    flight 3676: it went 4.5 m past that place before the new order came, and b flew up
    to it), and is let go again once the replan is made or given up."""
    today = _crossing_pair(offset_s=5.0)
    keeper = Gatekeeper(PassingOrder.derive(today.values(), margin_m=MARGIN_M), LIMITS)
    later = _crossing_pair(offset_s=-5.0)
    coming = PassingOrder.derive([p.after(10.0) for p in later.values()], margin_m=MARGIN_M)
    progress = _flying(today, {"a": 38.0, "b": 10.0})

    assert keeper.decide(progress, ["a", "b"]) == []  # today: a leads, nobody waits

    keeper.expect(coming, {"a": 10.0, "b": 10.0})
    [change] = keeper.decide(progress, ["a", "b"])
    assert (change.uav_id, change.gate, change.waits_for) == ("a", Gate.STOP, "b")
    assert change.gap_m < 50.0 - 6.0 - 38.0  # short of the crossing by at least 2R

    keeper.expect_nothing()
    [change] = keeper.decide(progress, ["a", "b"])
    assert (change.uav_id, change.gate) == ("a", Gate.GO)

"""The passing order judged on old positions: a vehicle whose positions were lost for a
while is taken to have flown on (`Gatekeeper._reckoned`); the one it waits for is not."""

from __future__ import annotations

from gcs.fleet.gatekeeper import FRESH_S, Gatekeeper
from gcs.fleet.path_progress import PathProgress
from gcs.mission.geodesy import GridFrame
from gcs.mission.motion import CopterLimits, Gate
from gcs.mission.passing_order import PassingOrder
from tests.unit.test_passing_order import _crossing_pair

FRAME = GridFrame(-35.3632, 149.1652, 584.0, 1.0)
LIMITS = {"a": CopterLimits(speed_m_s=10.0), "b": CopterLimits(speed_m_s=10.0)}
HEARD_AT = 100.0


def _keeper_and_progress() -> tuple[Gatekeeper, dict[str, PathProgress]]:
    """b crosses after a, whose position is where it starts; b flies toward its limit
    (about 43 m along) at 6.9 m/s, speeding up at 2.5 m/s², last heard at HEARD_AT."""
    paths = _crossing_pair(offset_s=5.0)
    keeper = Gatekeeper(PassingOrder.derive(paths.values(), margin_m=0.5), LIMITS)
    progress = {uav: PathProgress(path, FRAME) for uav, path in paths.items()}
    b = progress["b"]
    b.s, b.speed, b.accel, b.heard_at = 10.5, 6.9, 2.5, HEARD_AT
    return keeper, progress


def test_a_vehicle_unheard_for_a_while_is_stopped_where_it_may_be_by_now() -> None:
    """Gap swap at 10 m/s with 20 % loss: b's positions were lost for 1.2 s while it sped
    up, and judged where last heard it was let fly on until its pause could no longer
    stop it short (3.8 m past, 5.66 m from a)."""
    keeper, progress = _keeper_and_progress()
    assert keeper.decide(progress, ["b"], now=HEARD_AT + FRESH_S) == []

    [change] = keeper.decide(progress, ["b"], now=HEARD_AT + FRESH_S + 1.2)
    assert (change.uav_id, change.gate, change.waits_for) == ("b", Gate.STOP, "a")
    limit = keeper.order.limit("b", {"a": 0.0, "b": 10.5}).at_m
    assert change.gap_m < limit - 10.5 - 9.0  # it flew on at least 9 m meanwhile


def test_the_vehicle_waited_for_counts_where_it_was_last_heard() -> None:
    """a, unheard for long, is not taken to have crossed: b still waits for it."""
    keeper, progress = _keeper_and_progress()
    a = progress["a"]
    a.s, a.speed, a.accel, a.heard_at = 40.0, 10.0, 0.0, HEARD_AT
    b = progress["b"]
    b.s, b.speed, b.accel, b.heard_at = 40.0, 0.0, 0.0, HEARD_AT + 30.0
    keeper.gates["b"] = Gate.STOP
    keeper.decide(progress, ["a", "b"], now=HEARD_AT + 30.0)
    assert keeper.gates["b"] == Gate.STOP
    assert keeper.waits_for["b"] == "a"

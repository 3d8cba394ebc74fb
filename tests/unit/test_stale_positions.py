"""The gatekeeper's judgement of where a vehicle is: one whose positions were lost for a
while is taken to have flown on (`Gatekeeper._reckoned`), the one it waits for is not;
and one approaching a limit that has moved on is sped up."""

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


def test_an_approach_whose_limit_moved_on_is_sped_up() -> None:
    """b approaches its limit at 1 m/s; judged 20 m short of it (its limit moved on with
    its leader), it is given a faster approach, once: a change naming the new speed."""
    keeper, progress = _keeper_and_progress()
    b = progress["b"]
    limit = keeper.order.limit("b", {"a": 0.0, "b": 0.0}).at_m
    b.s, b.speed, b.accel, b.heard_at = limit - 20.0, 1.0, 0.0, HEARD_AT
    keeper.gates["b"], keeper.waits_for["b"], keeper.approach["b"] = Gate.CREEP, "a", 1.0
    [change] = keeper.decide(progress, ["b"], now=HEARD_AT)
    assert (change.gate, change.waits_for) == (Gate.CREEP, "a")
    assert change.speed_m_s is not None and change.speed_m_s > 1.5, change
    assert keeper.decide(progress, ["b"], now=HEARD_AT) == []  # given already

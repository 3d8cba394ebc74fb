"""The pauses of a flight nobody followed (gcs/service/flights/operator.py): every vehicle
flying its mission is paused at once, not one after another; a vehicle the operator
commanded first is left alone; after a cancelled start, a vehicle not yet seen flying
its mission is watched for a while, since the start's commands may still land."""

from __future__ import annotations

import asyncio
from types import SimpleNamespace
from typing import Any, ClassVar

import pytest

from gcs.service.flights import operator as operator_module
from gcs.service.flights.operator import OperatorCommands

pytestmark = pytest.mark.virtual_clock

BINDINGS = {"uav1": "v1", "uav2": "v2", "uav3": "v3"}


class Book:
    def __init__(self) -> None:
        self.told: list[dict[str, Any]] = []
        self.events = SimpleNamespace(record=lambda *args: None)

    def tell(self, _flight_id: str, message: dict[str, Any]) -> None:
        self.told.append(message)


class Registry:
    """Every vehicle online and armed, in its mode (flying its mission unless told)."""

    def __init__(self) -> None:
        self.modes: dict[str, str] = {}

    def link_or_none(self, vehicle_id: str) -> Any:
        mode = self.modes.get(vehicle_id, "AUTO")
        return SimpleNamespace(id=vehicle_id, state=SimpleNamespace(mode=mode, armed=True))


class Actions:
    """Pauses that each take a while to be answered (a lossy link)."""

    started: ClassVar[list[str]] = []
    answered: ClassVar[list[str]] = []
    most_at_once: ClassVar[int] = 0

    def __init__(self, link: Any) -> None:
        self.link = link

    async def pause(self) -> None:
        Actions.started.append(self.link.id)
        Actions.most_at_once = max(
            Actions.most_at_once, len(Actions.started) - len(Actions.answered)
        )
        await asyncio.sleep(0.5)
        Actions.answered.append(self.link.id)


@pytest.fixture
def ops(monkeypatch: pytest.MonkeyPatch) -> OperatorCommands:
    Actions.started, Actions.answered, Actions.most_at_once = [], [], 0
    monkeypatch.setattr(operator_module, "FlightActions", Actions)
    return OperatorCommands(SimpleNamespace(book=Book()), Registry())  # type: ignore[arg-type]


def unfollow(ops: OperatorCommands, watch_s: float = 0.0) -> None:
    """`pause_unfollowed` without its watch until every vehicle is down."""
    ops._unfollowed["f"] = {vid: uav for uav, vid in BINDINGS.items()}
    ops._unfollowed_until["f"] = asyncio.get_running_loop().time() + watch_s


async def test_every_vehicle_is_paused_at_once(ops: OperatorCommands) -> None:
    unfollow(ops)
    await ops._pause_unfollowed("f")
    assert Actions.started == ["v1", "v2", "v3"]
    assert Actions.most_at_once == 3  # none waited for another's answer
    assert len(Actions.answered) == 3
    assert [m["uav_id"] for m in ops.book.told] == ["uav1", "uav2", "uav3"]  # type: ignore[attr-defined]
    assert ops._unfollowed["f"] == {}  # each tried once


async def test_a_vehicle_the_operator_commanded_first_is_left_alone(ops: OperatorCommands) -> None:
    unfollow(ops)
    ops.operator_took("f", "v2")
    await ops._pause_unfollowed("f")
    assert Actions.started == ["v1", "v3"]


async def test_an_abort_first_ends_the_pausing(ops: OperatorCommands) -> None:
    unfollow(ops)
    ops.operator_took("f")
    await ops._pause_unfollowed("f")
    assert Actions.started == []


async def test_after_a_cancelled_start_a_vehicle_not_yet_in_its_mission_is_watched(
    ops: OperatorCommands,
) -> None:
    """The start's AUTO may land after the cancel: a vehicle still in GUIDED is looked at
    again until the watch ends, then let go."""
    modes = {"v1": "AUTO", "v2": "GUIDED", "v3": "GUIDED"}
    ops.registry.modes = modes  # type: ignore[attr-defined]
    unfollow(ops, watch_s=5.0)
    await ops._pause_unfollowed("f")
    assert Actions.started == ["v1"]
    modes["v2"] = "AUTO"  # its AUTO landed late
    await ops._pause_unfollowed("f")
    assert Actions.started == ["v1", "v2"]
    await asyncio.sleep(5.0)  # the watch is over: v3 never started its mission
    await ops._pause_unfollowed("f")
    assert ops._unfollowed["f"] == {}
    assert Actions.started == ["v1", "v2"]

"""The pauses of a flight nobody followed (gcs/service/flights/operator.py) give way to the
operator: a vehicle the operator commands while another is being paused is not paused
afterwards, and an abort meanwhile stops the pausing altogether."""

from __future__ import annotations

import asyncio
from types import SimpleNamespace
from typing import Any

import pytest

from gcs.service.flights import operator as operator_module
from gcs.service.flights.operator import OperatorCommands

BINDINGS = {"uav1": "v1", "uav2": "v2", "uav3": "v3"}


class Book:
    def __init__(self) -> None:
        self.told: list[dict[str, Any]] = []
        self.events = SimpleNamespace(record=lambda *args: None)

    def tell(self, _flight_id: str, message: dict[str, Any]) -> None:
        self.told.append(message)


class Registry:
    """Every vehicle online, armed and flying its mission."""

    def link_or_none(self, vehicle_id: str) -> Any:
        return SimpleNamespace(id=vehicle_id, state=SimpleNamespace(mode="AUTO", armed=True))


def commands(monkeypatch: pytest.MonkeyPatch, meanwhile: str) -> tuple[OperatorCommands, list]:
    """An operator whose first pause (of v1) lets the operator act: on v2, or an abort."""
    paused: list[str] = []
    ops = OperatorCommands(SimpleNamespace(book=Book()), Registry())  # type: ignore[arg-type]

    class Actions:
        def __init__(self, link: Any) -> None:
            self.link = link

        async def pause(self) -> None:
            paused.append(self.link.id)
            if self.link.id == "v1":
                await asyncio.sleep(0)  # the operator's command comes in meanwhile
                ops.operator_took("f", "v2" if meanwhile == "hold v2" else None)

    monkeypatch.setattr(operator_module, "FlightActions", Actions)
    ops._unfollowed["f"] = {vid: uav for uav, vid in BINDINGS.items()}
    return ops, paused


async def test_a_vehicle_the_operator_commands_meanwhile_is_not_paused(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    ops, paused = commands(monkeypatch, "hold v2")
    await ops._pause_unfollowed("f")
    assert paused == ["v1", "v3"]
    assert [m["uav_id"] for m in ops.book.told] == ["uav1", "uav3"]  # type: ignore[attr-defined]


async def test_an_abort_meanwhile_ends_the_pausing(monkeypatch: pytest.MonkeyPatch) -> None:
    ops, paused = commands(monkeypatch, "abort")
    await ops._pause_unfollowed("f")
    assert paused == ["v1"]

"""A flight taken over in the air resumes by itself (gcs/service/flights/operator.py)
once every vehicle is heard and every pause owed to it was tried; the operator's
command first calls it off, and a vehicle never heard leaves it interrupted, said so."""

from __future__ import annotations

import asyncio
from types import SimpleNamespace
from typing import Any

import pytest

from gcs.service.flights.operator import RESUME_WITHIN_S, OperatorCommands
from gcs.service.states import FlightState

pytestmark = [pytest.mark.virtual_clock]
BINDINGS = {"uav1": "v1", "uav2": "v2"}


class Book:
    def __init__(self) -> None:
        self.told: list[dict[str, Any]] = []
        self.events = SimpleNamespace(record=lambda *args: None)
        self.flight_state = FlightState.INTERRUPTED

    async def bindings(self, _flight_id: str) -> dict[str, str]:
        return BINDINGS

    async def state(self, _flight_id: str) -> FlightState:
        return self.flight_state

    def tell(self, _flight_id: str, message: dict[str, Any]) -> None:
        self.told.append(message)


class Registry:
    def __init__(self) -> None:
        self.heard = {"v1"}

    def link_or_none(self, vehicle_id: str) -> Any:
        return object() if vehicle_id in self.heard else None


def commands() -> tuple[OperatorCommands, Book, Registry, list[str]]:
    book, registry, resumed = Book(), Registry(), []
    ops = OperatorCommands(SimpleNamespace(book=book), registry)  # type: ignore[arg-type]

    async def resume(flight_id: str, why: str) -> list[Any]:
        resumed.append(why)
        book.flight_state = FlightState.FLYING
        return [SimpleNamespace(uav_id="uav1", detail="mission paused")]

    ops.resume = resume  # type: ignore[method-assign, assignment]
    return ops, book, registry, resumed


async def test_it_resumes_once_every_vehicle_is_heard_and_paused() -> None:
    ops, book, registry, resumed = commands()
    ops._unfollowed["f"] = {"v2": "uav2"}  # v2's pause still owed
    ops.resume_when_heard("f", "by service b")
    await asyncio.sleep(5.0)
    assert resumed == []  # v2 not heard yet
    registry.heard.add("v2")
    await asyncio.sleep(5.0)
    assert resumed == []  # heard, but its pause not tried yet
    ops._unfollowed["f"].clear()
    await asyncio.sleep(1.0)
    assert resumed == ["by service b"]
    assert book.told[-1]["kind"] == "AutoResumed" and book.told[-1]["ok"], book.told


@pytest.mark.parametrize("command", ["abort", "one vehicle"])
async def test_the_operators_command_calls_it_off(command: str) -> None:
    ops, book, registry, resumed = commands()
    ops.resume_when_heard("f", "by service b")
    await asyncio.sleep(1.0)
    ops.operator_took("f", None if command == "abort" else "v1")
    registry.heard.add("v2")
    await asyncio.sleep(RESUME_WITHIN_S)
    assert resumed == [] and book.told == []


async def test_a_vehicle_never_heard_leaves_it_interrupted_and_says_so() -> None:
    ops, book, _registry, resumed = commands()
    ops.resume_when_heard("f", "by service b")
    await asyncio.sleep(RESUME_WITHIN_S + 1.0)
    assert resumed == []
    assert book.told[-1]["kind"] == "AutoResumed" and not book.told[-1]["ok"]
    assert "not every vehicle heard" in book.told[-1]["detail"]

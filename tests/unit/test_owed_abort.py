"""An abort owed to vehicles it has not reached yet (gcs/service/flights/operator.py) is
sent to each once it is back, unless a later abort has taken over meanwhile."""

from __future__ import annotations

import asyncio
from types import SimpleNamespace
from typing import Any

import pytest

from gcs.fleet.crew import Fallback
from gcs.service.flights import operator as operator_module
from gcs.service.flights.operator import OperatorCommands

pytestmark = pytest.mark.virtual_clock


class Registry:
    """Every vehicle back online, in the air."""

    def link_or_none(self, vehicle_id: str) -> Any:
        return SimpleNamespace(id=vehicle_id, state=SimpleNamespace(down=False))


async def test_an_owed_abort_is_given_up_once_a_later_abort_takes_over(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Fuzzed flight 10380 (6 UAVs, a restart, then the operator's abort with RTL and,
    0.2 s later, with LAND): the RTL owed to uav4, offline when the first abort went out,
    was sent once it was back, while the LAND went out, and after it; uav4 flew home.
    Here the RTL owed to two vehicles takes 0.5 s to be answered by the first, and the
    later abort (which reached both) comes meanwhile: the second gets no RTL."""
    sent: list[tuple[str, str]] = []

    class Actions:
        def __init__(self, link: Any) -> None:
            self.link = link

        async def return_to_launch(self) -> None:
            sent.append(("RTL", self.link.id))
            await asyncio.sleep(0.5)

    monkeypatch.setattr(operator_module, "FlightActions", Actions)
    ops = OperatorCommands(SimpleNamespace(book=None), Registry())  # type: ignore[arg-type]
    ops._owed["f"] = (Fallback.RTL, {"v1", "v2"})
    paying = asyncio.ensure_future(ops._pay_what_is_owed("f"))
    await asyncio.sleep(0.1)
    ops._owed["f"] = (Fallback.LAND, set())  # the later abort, which reached both
    await paying
    assert sent == [("RTL", "v1")]

    ops._owed["f"] = (Fallback.RTL, {"v1", "v2"})  # nobody takes over: both are paid
    sent.clear()
    await ops._pay_what_is_owed("f")
    assert sent == [("RTL", "v1"), ("RTL", "v2")]

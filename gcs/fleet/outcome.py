"""What one vehicle answered to a fleet operation, and running an operation on many."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass
from typing import Generic, TypeVar

from gcs.fleet.member import Member
from gcs.mavlink.errors import GcsError

T = TypeVar("T")
EXPECTED_FAILURES = (GcsError, OSError, ValueError, TimeoutError)
"""What a vehicle can do to an operation: refuse, time out, drop the link."""


@dataclass(frozen=True)
class VehicleOutcome(Generic[T]):
    """One vehicle's answer to a fleet operation."""

    uav_id: str
    ok: bool
    detail: str
    value: T | None = None
    error: BaseException | None = None
    seconds: float | None = None  # from the operation's start to this vehicle's answer


async def run_each(
    members: Iterable[Member],
    action: Callable[[Member], Awaitable[T]],
    on_failure: Callable[[str, str], None] | None = None,
) -> dict[str, VehicleOutcome[T]]:
    """`action` on every member at once; one vehicle's failure does not stop the others.

    Failures a vehicle can cause become a failed outcome (and `on_failure(uav, message)`);
    anything else (a bug, a cancellation) propagates."""
    chosen = list(members)
    loop = asyncio.get_running_loop()
    began = loop.time()
    answered: dict[str, float] = {}

    async def timed(member: Member) -> T:
        try:
            return await action(member)
        finally:
            answered[member.uav_id] = loop.time() - began

    results = await asyncio.gather(*(timed(m) for m in chosen), return_exceptions=True)
    outcomes: dict[str, VehicleOutcome[T]] = {}
    for member, result in zip(chosen, results, strict=True):
        uav, seconds = member.uav_id, answered.get(member.uav_id)
        if isinstance(result, EXPECTED_FAILURES):
            if on_failure is not None:
                on_failure(uav, str(result))
            outcomes[uav] = VehicleOutcome(uav, False, str(result), None, result, seconds)
        elif isinstance(result, BaseException):
            raise result
        else:
            detail = result if isinstance(result, str) else "ok"  # a hold says how
            outcomes[uav] = VehicleOutcome(uav, True, detail, result, None, seconds)
    return outcomes

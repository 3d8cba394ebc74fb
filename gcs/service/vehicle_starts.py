"""Starts "where vehicle X is now": a geographic scenario's start that names a registered
vehicle (`"vehicle": "<id>"`, geometry null) is placed at the position that vehicle last
reported, when the file is posted. The stored file holds the position used, so the
scenario stays what was planned even after the vehicle moves."""

from __future__ import annotations

from typing import Any

from gcs.mission.geographic import GeographicError, placed_at, vehicle_starts
from gcs.service.vehicle_registry import VehicleRegistry

MAX_POSITION_AGE_S = 5.0
"""A position older than this is not where the vehicle is now (GLOBAL_POSITION_INT comes
several times a second from a connected autopilot)."""


def place_vehicle_starts(data: Any, registry: VehicleRegistry, now: float) -> Any:
    """The file with every vehicle-placed start filled in; GeographicError naming the
    start when its vehicle is unknown, has no position yet or has gone quiet. `now` is
    the event loop's time, the clock positions are heard on."""
    for index, where, vehicle in vehicle_starts(data):
        if not registry.knows(vehicle):
            raise GeographicError(where, f"vehicle {vehicle!r} is not registered")
        state = registry.vehicle_state(vehicle)
        if state is None or state.position is None or state.position_heard is None:
            why = registry.why_offline(vehicle)
            raise GeographicError(where, f"vehicle {vehicle!r} has no position yet ({why})")
        age = now - state.position_heard
        if age > MAX_POSITION_AGE_S:
            raise GeographicError(
                where, f"vehicle {vehicle!r} last reported its position {age:.0f} s ago"
            )
        data = placed_at(data, index, state.position.lat, state.position.lon)
    return data

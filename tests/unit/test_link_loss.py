"""The GCS failsafe a flight gives each ArduCopter (`gcs.fleet.link_loss`), against a
scripted autopilot's parameters, on the virtual clock."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.fleet.link_loss import FailsafeSetupError, brake_on_link_loss
from gcs.mavlink.link import VehicleLink
from tests.unit.test_mavlink_in_memory import Peer, Reply, linked, silent

pytestmark = pytest.mark.virtual_clock


def parameters(peer: Peer, values: dict[str, float], refused: frozenset[str]) -> Reply:
    """An autopilot holding `values`: it answers reads of them and takes sets, but those
    of `refused`, which it never answers."""

    def reply(msg: Any) -> list[Any]:
        kind = msg.get_type()
        if kind not in ("PARAM_REQUEST_READ", "PARAM_SET"):
            return []
        name = msg.param_id.rstrip("\x00") if isinstance(msg.param_id, str) else msg.param_id
        if name not in values or name in refused:
            return []
        if kind == "PARAM_SET":
            values[name] = msg.param_value
        value = peer.codec.param_value_encode(
            name.encode(), values[name], mavlink2.MAV_PARAM_TYPE_REAL32, len(values), 0
        )
        return [value]

    return reply


async def clock_runs_twice_as_fast(link: VehicleLink, peer: Peer) -> None:
    """The vehicle's clock (`time_boot_ms`) says 4 s went by while 2 s of ours did."""
    for boot_ms in (10_000, 12_000, 14_000):
        peer.heartbeat()
        peer.send(peer.codec.system_time_encode(0, boot_ms))
        if boot_ms < 14_000:
            await asyncio.sleep(1.0)
    assert link.clock_rate() == pytest.approx(2.0, rel=0.01)


async def fly_with(
    values: dict[str, float], brake_after_s: float, refused: frozenset[str] = frozenset()
) -> tuple[list[str], float | None]:
    """The parameters a flight's upload sets on such an autopilot, in order, and how long
    the vehicle is said to fly on unheard (its own seconds)."""
    link, peer = await linked(silent)
    peer.reply = parameters(peer, values, refused)
    await clock_runs_twice_as_fast(link, peer)  # a SITL at speed-up 2
    try:
        silent_s = await brake_on_link_loss(link, brake_after_s)
    finally:
        await link.close()
    return [m.param_id for m in peer.sent("PARAM_SET")], silent_s


async def test_an_arducopter_brakes_after_two_of_our_seconds_and_lands_on_if_landing() -> None:
    values = {"FS_GCS_ENABLE": 0.0, "FS_GCS_TIMEOUT": 5.0, "FS_OPTIONS": 16.0}
    sets, silent_s = await fly_with(values, 2.0)
    assert sets == ["FS_GCS_TIMEOUT", "FS_OPTIONS", "FS_GCS_ENABLE"]  # enabled last
    assert silent_s == 4.0
    assert values == {"FS_GCS_ENABLE": 7.0, "FS_GCS_TIMEOUT": 4.0, "FS_OPTIONS": 24.0}


async def test_what_is_there_already_or_not_there_is_left_as_it_is() -> None:
    """Options that let landings go on already are not set again; firmware before
    FS_GCS_TIMEOUT (ArduCopter 4.2 and older) keeps its fixed 5 s."""
    values = {"FS_GCS_ENABLE": 0.0, "FS_OPTIONS": 8.0}
    assert await fly_with(values, 2.0) == (["FS_GCS_ENABLE"], 5.0)
    assert values == {"FS_GCS_ENABLE": 7.0, "FS_OPTIONS": 8.0}


async def test_zero_seconds_leave_the_vehicles_own_failsafe_alone() -> None:
    values = {"FS_GCS_ENABLE": 0.0, "FS_GCS_TIMEOUT": 5.0, "FS_OPTIONS": 16.0}
    assert await fly_with(values, 0.0) == ([], None)


async def test_a_vehicle_that_does_not_take_it_refuses_the_flight() -> None:
    values = {"FS_GCS_ENABLE": 0.0, "FS_GCS_TIMEOUT": 5.0, "FS_OPTIONS": 16.0}
    with pytest.raises(FailsafeSetupError, match=r"GCS failsafe.*flight refused"):
        await fly_with(values, 2.0, refused=frozenset({"FS_GCS_ENABLE"}))

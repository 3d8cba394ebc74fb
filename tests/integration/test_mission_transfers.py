"""Upload, download, clear and set-current against simulated vehicles, and the mission
protocol's failure modes (numbers as in the MAVLink notes), on the virtual clock: the
vehicles in memory, their faults (loss, latency, jitter, silence, reboots) on the one
clock, so the protocol's timeouts are tested without waiting for them. The same
transfers over real sockets are the conformance tests'."""

from __future__ import annotations

import asyncio
from dataclasses import replace

import pytest

from gcs.mavlink.errors import (
    GcsError,
    LinkLostError,
    MissionDeniedError,
    MissionGenericError,
    MissionMismatchError,
    MissionResult,
    MissionTimeoutError,
    NoSpaceError,
)
from gcs.mavlink.mission_item import Autopilot, Command, Mission, MissionItem
from gcs.mavlink.mission_protocol import MissionClient, TransferPolicy, first_mismatch
from gcs.mavlink.vehicle_state import MAV_STATE_BOOT
from sitl_mock import Faults, VehicleConfig

from .conftest import CMAC, FAST_LINK, square_mission, vehicle

pytestmark = [pytest.mark.virtual_clock]
BOTH = ["ardupilot", "px4"]


def sent_types(link) -> list[str]:
    """Record the type of every message the link sends from now on."""
    sent: list[str] = []
    original = link.send

    def send(msg) -> None:
        sent.append(msg.get_type())
        original(msg)

    link.send = send
    return sent


@pytest.mark.parametrize("autopilot", BOTH)
async def test_upload_download_set_current_and_clear(simulator, links, autopilot: str) -> None:
    sim = await simulator([vehicle(1, autopilot)])
    link = await links(sim, 1)
    client = MissionClient(link)
    mission = square_mission(link.autopilot, hold_s=2.5)
    result = await client.upload(mission)
    assert result.verified and result.items == len(mission)
    assert [i.command for i in sim.mission(1)][-1] == Command.NAV_LAND
    assert first_mismatch(mission, await client.download()) is None
    await client.set_current(3)
    assert sim.state(1).mission_seq == 3
    await client.clear()
    remaining = await client.download()
    assert len(remaining) == (1 if link.autopilot == Autopilot.ARDUPILOT else 0)  # home stays


async def test_ardupilot_item_zero_is_home_and_never_eats_the_takeoff(simulator, links) -> None:
    """Failure mode 2: seq 0 comes back as the vehicle's home, the takeoff stays seq 1."""
    sim = await simulator([vehicle(1, "ardupilot")])
    link = await links(sim, 1)
    mission = square_mission(Autopilot.ARDUPILOT)
    bogus_home = replace(mission.items[0], x=mission.items[0].x + 5000, z=0.0)
    mission = Mission((bogus_home, *mission.items[1:]), Autopilot.ARDUPILOT, CMAC)
    await MissionClient(link).upload(mission)  # verification skips seq 0
    stored = sim.mission(1)
    assert stored[1].command == Command.NAV_TAKEOFF
    assert stored[0].x == round(CMAC[0] * 1e7)  # the vehicle's own home


async def test_a_mission_of_the_wrong_flavour_is_refused_before_sending(simulator, links):
    sim = await simulator([vehicle(1, "px4")])
    link = await links(sim, 1)
    with pytest.raises(GcsError, match="built for ARDUPILOT"):
        await MissionClient(link).upload(square_mission(Autopilot.ARDUPILOT))


@pytest.mark.parametrize("autopilot", BOTH)
async def test_an_empty_mission_does_not_hang(simulator, links, autopilot: str) -> None:
    """Failure mode 11: count 0 clears the mission and returns at once."""
    sim = await simulator([vehicle(1, autopilot)])
    link = await links(sim, 1)
    client = MissionClient(link)
    await client.upload(square_mission(link.autopilot))
    sent = sent_types(link)
    await asyncio.wait_for(client.upload(Mission((), link.autopilot)), timeout=30.0)
    assert sent.count("MISSION_COUNT") == 1  # answered at once, nothing re-sent
    assert not sim.mission(1)[1:]


async def test_an_upload_right_after_boot_waits_for_the_boot_to_end(simulator, links) -> None:
    """Real ArduCopter answers MISSION_COUNT with NO_SPACE while it boots."""
    sim = await simulator([vehicle(1)])
    link = await links(sim, 1, settings=replace(FAST_LINK, link_timeout_s=4.0))
    assert link.state.booting
    mission = square_mission(link.autopilot)
    assert (await MissionClient(link).upload(mission)).verified
    assert len(sim.mission(1)) == len(mission)


async def test_timeouts_are_settable(simulator, links) -> None:
    """Failure mode 1: a slow link needs longer timeouts than a fast one."""
    sim = await simulator([vehicle(1, faults=Faults(latency_s=0.15))])
    link = await links(sim, 1)
    mission = square_mission(link.autopilot, n_waypoints=1)
    impatient = MissionClient(
        link, TransferPolicy(step_timeout_s=0.1, item_timeout_s=0.05, retries=1)
    )
    with pytest.raises(MissionTimeoutError):
        await impatient.upload(mission)
    patient = MissionClient(link, TransferPolicy(step_timeout_s=1.0, item_timeout_s=0.5))
    assert (await patient.upload(mission)).verified


async def test_invalid_sequence_mid_transfer_is_not_fatal(simulator, links) -> None:
    """Failure mode 3 (and 7's duplicates): reordered and doubled packets both ways."""
    faults = Faults(duplicate=0.3, reorder=0.3)
    sim = await simulator([vehicle(1, faults=faults)], seed=3)
    link = await links(sim, 1)
    acks: list[int] = []
    link.on_message(lambda m: acks.append(m.type), ["MISSION_ACK"])
    for _ in range(3):
        assert (await MissionClient(link).upload(square_mission(link.autopilot, 8))).verified
    assert MissionResult.INVALID_SEQUENCE in acks


async def test_a_lost_final_ack_is_recovered_by_resending_the_last_item(simulator, links):
    """Failure mode 4: the vehicle re-acknowledges a repeated last item."""
    sim = await simulator([vehicle(1)])
    link = await links(sim, 1)
    deliver = link._received
    dropped: list[int] = []

    def drop_first_accepting_ack(msg) -> None:
        if msg.get_type() == "MISSION_ACK" and msg.type == 0 and not dropped:
            dropped.append(1)
            return
        deliver(msg)

    link.connection.attach(link.sysid, drop_first_accepting_ack)
    sent = sent_types(link)
    mission = square_mission(link.autopilot)
    assert (await MissionClient(link).upload(mission)).verified
    assert dropped
    assert sent.count("MISSION_ITEM_INT") == len(mission) + 1


async def test_a_noisy_link_completes_every_upload(simulator, links) -> None:
    """Failure mode 5: 30 % loss each way and 200 ms jitter, 20 of 20 uploads verified."""
    faults = Faults(loss_in=0.3, loss_out=0.3, jitter_s=0.2)
    flavours = ["ardupilot", "px4"] * 10
    sim = await simulator(
        [vehicle(k, flavours[k - 1], faults=faults) for k in range(1, 21)], seed=5
    )
    connected = await asyncio.gather(
        *(
            links(sim, k, settings=replace(FAST_LINK, link_timeout_s=4.0, connect_timeout_s=10.0))
            for k in range(1, 21)
        )
    )
    results = await asyncio.gather(
        *(MissionClient(link).upload(square_mission(link.autopilot, 4)) for link in connected)
    )
    assert [r.verified for r in results] == [True] * 20
    for k, link in enumerate(connected, start=1):
        assert len(sim.mission(k)) == len(square_mission(link.autopilot, 4))


async def test_verification_catches_a_mission_changed_behind_our_back(
    simulator, links, monkeypatch: pytest.MonkeyPatch
):
    """Failure mode 6: what the vehicle holds is compared item by item after the upload."""
    sim = await simulator([vehicle(1)])
    link = await links(sim, 1)
    other_gcs = await links(sim, 1)
    ours, theirs = square_mission(link.autopilot, 4), square_mission(link.autopilot, 4, 3.0)
    client = MissionClient(link)
    download = client._download

    async def someone_else_uploads_first() -> tuple[MissionItem, ...]:
        await MissionClient(other_gcs).upload(theirs)
        return await download()

    monkeypatch.setattr(client, "_download", someone_else_uploads_first)
    with pytest.raises(MissionMismatchError, match="seq 3") as caught:
        await client.upload(ours)
    assert caught.value.seq == 3


async def test_a_rejected_mission_keeps_the_previous_one(simulator, links) -> None:
    sim = await simulator([vehicle(1)])
    link = await links(sim, 1)
    client = MissionClient(link)
    previous = square_mission(link.autopilot, 2)
    await client.upload(previous)
    sim.set_faults(1, Faults(reject_missions=True))
    with pytest.raises(MissionGenericError, match="upload at item seq 8"):
        await client.upload(square_mission(link.autopilot, 5))
    assert len(sim.mission(1)) == len(previous)
    assert not sim.state(1).armed


async def test_definitive_refusals_are_not_retried(simulator, links) -> None:
    """Failure mode 7: NO_SPACE ends the upload after one MISSION_COUNT."""
    config = VehicleConfig(sysid=1, home=CMAC, mission_capacity=5)
    sim = await simulator([config])
    link = await links(sim, 1)
    sent = sent_types(link)
    with pytest.raises(NoSpaceError, match="more items than the vehicle can store"):
        await MissionClient(link).upload(square_mission(link.autopilot, 6))
    assert sent.count("MISSION_COUNT") == 1


async def test_every_wait_is_bounded(simulator, links) -> None:
    """Failure mode 8: a vehicle gone silent mid-upload ends in an error, not a hang."""
    sim = await simulator([vehicle(1)])
    link = await links(sim, 1)
    sim.silence(1, seconds=2000.0)
    async with asyncio.timeout(60):  # a hang detector, far above the protocol's own bounds
        with pytest.raises((LinkLostError, MissionTimeoutError)):
            await MissionClient(link).upload(square_mission(link.autopilot))
        with pytest.raises((LinkLostError, MissionTimeoutError)):
            await MissionClient(link).download()


async def test_another_ground_station_mid_upload_is_denied_without_retrying(simulator, links):
    """Failure mode 9: DENIED once, no re-request loop."""
    sim = await simulator([vehicle(1)])
    link = await links(sim, 1)
    other_gcs = await links(sim, 1)
    await until_booted(link)
    with other_gcs.subscribe(["MISSION_REQUEST", "MISSION_REQUEST_INT"]) as asked:
        other_gcs.send(other_gcs.codec.mission_count_encode(1, 1, 5, 0))  # and never answers
        await asked.get(10.0)  # the vehicle is now busy with the other ground station
    sent = sent_types(link)
    with pytest.raises(MissionDeniedError, match="another ground station"):
        await MissionClient(link).upload(square_mission(link.autopilot))
    assert sent.count("MISSION_COUNT") == 1


async def test_a_reboot_mid_upload_ends_in_a_clear_error(simulator, links) -> None:
    sim = await simulator([vehicle(1, faults=Faults(latency_s=0.5))])
    # The default link timeout (the notes: 3-5 s): at the tests' quick 1 s, the reboot's
    # silence (1 s, seen 0.5 s late) would end the upload as a lost link before the new
    # boot is heard.
    link = await links(sim, 1, settings=replace(FAST_LINK, link_timeout_s=4.0))
    await until_booted(link)
    with link.subscribe(["MISSION_REQUEST", "MISSION_REQUEST_INT"]) as asked:
        upload = asyncio.create_task(MissionClient(link).upload(square_mission(link.autopilot, 30)))
        await asked.get(10.0)  # items are flowing
    sim.reboot(1)
    with pytest.raises(GcsError) as caught:
        await asyncio.wait_for(upload, timeout=12.0)
    assert "reboot" in str(caught.value) or isinstance(caught.value, MissionTimeoutError)
    state = sim.state(1)
    assert not state.armed and not sim.mission(1)[1:]


async def until_booted(link) -> None:
    """Until the vehicle's HEARTBEAT leaves BOOT (it refuses uploads while booting)."""
    if link.state.booting:
        await link.wait_for("HEARTBEAT", lambda hb: hb.system_status != MAV_STATE_BOOT, 30.0)

"""The fence and rally points our flights upload, seen by three independent clients
(issue 26, item 4): the ground station writes a geographic scenario's fence and rally
points to a simulated ArduCopter over TCP (gcs/fleet/geofence.py), then pymavlink,
MAVSDK (mission_raw's download_geofence and download_rallypoints, MAVSDK 4.1) and
MAVProxy (`fence list`, `rally list`) each download them and find them item by item as
ArduPilot keeps them: vertices and radii as sent, in frame 0 with z 0; rally points in
frame 3 at whole metres."""

from __future__ import annotations

import asyncio
import json
import re
import time
from collections.abc import Iterator
from pathlib import Path

import mavsdk.asyncio as mavsdk
import pytest
from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync

from gcs.fleet.geofence import GeoFence, enable_fence, upload_fence
from gcs.mavlink import client
from gcs.mavlink.link import LinkSettings
from gcs.mavlink.mission_item import MissionItem
from gcs.mavlink.mission_protocol import MissionClient
from gcs.mission.fence import FencePlan, fence_items, fence_of, rally_items
from gcs.mission.geographic import load_geographic
from sitl_mock import Simulator, VehicleConfig
from sitl_mock.codec import mavlink
from tests.conformance.mavproxy_process import MavProxy
from tests.conformance.test_pymavlink_protocol import Gcs
from tests.geographic import EXAMPLE

SPEEDUP = 20.0
WAIT_S = 20.0
RALLY_ALT_M = 15.0
HOME = (-35.3650, 149.1645, 584.0)  # inside the example's field


def fence_plan() -> FencePlan:
    document = json.loads(EXAMPLE.read_text())
    for lon, lat, *alt in ([149.1650, -35.3652], [149.1690, -35.3630, 30.0]):
        document["features"].append(
            {
                "type": "Feature",
                "properties": {"role": "rally"},
                "geometry": {"type": "Point", "coordinates": [lon, lat, *alt]},
            }
        )
    return fence_of(load_geographic(document))


FENCE = fence_plan()
SENT_FENCE = fence_items(FENCE)
SENT_RALLY = rally_items(FENCE, RALLY_ALT_M)


def as_ardupilot_keeps(items: tuple[MissionItem, ...], fence: bool) -> list[tuple]:
    """(command, frame, param1, x, y, z) of our items as ArduPilot gives them back."""
    if fence:
        return [(i.command, 0, i.params[0], i.x, i.y, 0.0) for i in items]
    return [(i.command, 3, 0.0, i.x, i.y, float(int(i.z))) for i in items]


@pytest.fixture
def vehicle() -> Iterator[Simulator]:
    """One simulated ArduCopter holding the fence and rally points our ground station
    uploaded, with its fence enabled."""
    sim = Simulator([VehicleConfig(sysid=1, transport="tcp", home=HOME)], speedup=SPEEDUP, seed=0)
    with sim.running():
        asyncio.run(product_uploads(sim))
        yield sim


async def product_uploads(sim: Simulator) -> None:
    link = await client.connect(
        sim.connection_string(1), settings=LinkSettings(connect_timeout_s=WAIT_S)
    )
    try:
        geofence = GeoFence(FENCE, action=2)
        await upload_fence(MissionClient(link), geofence, RALLY_ALT_M)
        await enable_fence(link, geofence)
    finally:
        await link.close()
    assert sim.vehicle(1).params.get("FENCE_ENABLE") == 1


def test_the_fence_has_every_kind_of_item() -> None:
    commands = {i.command for i in SENT_FENCE}
    assert commands == {
        mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
        mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
        mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
    }
    assert [r.z for r in SENT_RALLY] == [15.0, 30.0]


def test_pymavlink_downloads_what_we_uploaded(vehicle: Simulator) -> None:
    gcs = Gcs(vehicle.connection_string(1))
    try:
        for mission_type, sent, fence in ((1, SENT_FENCE, True), (2, SENT_RALLY, False)):
            theirs = gcs.download(mission_type=mission_type)
            assert theirs is not None
            assert [(m.command, m.frame, m.param1, m.x, m.y, m.z) for m in theirs] == (
                as_ardupilot_keeps(sent, fence)
            )
        gcs.link.mav.param_request_read_send(1, 1, b"FENCE_ACTION", -1)
        assert gcs.recv("PARAM_VALUE").param_value == 2
    finally:
        gcs.close()


async def test_mavsdk_downloads_what_we_uploaded(vehicle: Simulator) -> None:
    kind, host, port = vehicle.connection_string(1).split(":")
    assert kind == "tcp"
    config = mavsdk.Configuration.create_with_component_type(mavsdk.ComponentType.GROUND_STATION)
    async with mavsdk.Mavsdk(config) as sdk:
        await sdk.add_any_connection(f"tcpout://{host}:{port}")
        system = await sdk.first_autopilot(timeout_s=WAIT_S)
        assert system is not None, "MAVSDK did not discover the simulated vehicle"
        raw = MissionRawAsync(system)
        for download, sent, fence in (
            (raw.download_geofence, SENT_FENCE, True),
            (raw.download_rallypoints, SENT_RALLY, False),
        ):
            theirs = await download()
            assert [(m.command, m.frame, m.param1, m.x, m.y, m.z) for m in theirs] == (
                as_ardupilot_keeps(sent, fence)
            )


LISTED = re.compile(r"^(\d+) (\d+) (-?[\d.]+) (-?[\d.]+) (-?[\d.]+) p1=(-?[\d.]+)")


def listed(proxy: MavProxy, command: str, count: int, after: int) -> list[tuple]:
    """The items MAVProxy printed for `fence list` / `rally list`: (command, frame, p1,
    latitude degE7, longitude degE7, z), waiting (bounded) for all of them."""
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        rows = [m for line in proxy.output[after:] if (m := LISTED.match(line))]
        if len(rows) >= count:
            break
        time.sleep(0.05)

    def deg_e7(text: str) -> int:
        value = float(text)
        return round(value if abs(value) > 1000 else value * 1e7)

    return [
        (int(c), int(f), float(p1), deg_e7(x), deg_e7(y), float(z))
        for c, f, x, y, z, p1 in (m.groups() for m in rows)
    ]


def test_mavproxy_lists_what_we_uploaded(vehicle: Simulator, tmp_path: Path) -> None:
    proxy = MavProxy(vehicle.connection_string(1), tmp_path)
    try:
        assert proxy.wait_for("online system 1", WAIT_S) is not None, proxy.output
        for command, sent, fence in (("fence", SENT_FENCE, True), ("rally", SENT_RALLY, False)):
            after = proxy.command(f"{command} list")
            theirs = listed(proxy, command, len(sent), after)
            assert theirs == [
                (c, f, float(p1), x, y, z) for c, f, p1, x, y, z in as_ardupilot_keeps(sent, fence)
            ], proxy.output[after:]
    finally:
        proxy.stop()

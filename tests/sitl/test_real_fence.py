"""The geofence on real ArduCopter SITL (issue 26, item 4): the ground station uploads a
fence and rally points (gcs/fleet/geofence.py), reads them back as ArduCopter keeps
them, enables the fence with a FENCE_ACTION, and flies a mission whose waypoint lies
beyond the fence: ArduCopter itself says "Polygon fence breached", reports the breach in
FENCE_STATUS and switches to the configured action's mode near the fence, whatever the
mission says. The same checks the mock's enforcement is held to (tests/integration/
test_geofence.py). And the service flies a geographic scenario with its fence enabled
to the end, without a breach. Run with `ARDUPILOT_SITL=/path/to/arducopter`; skipped
otherwise."""

from __future__ import annotations

import json
from pathlib import Path

import pymap3d
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.fleet.geofence import GeoFence, enable_fence, upload_fence
from gcs.mavlink import client
from gcs.mavlink.actions import FlightActions, ReadinessPolicy
from gcs.mavlink.commands import CommandPolicy
from gcs.mavlink.link import LinkSettings, VehicleLink
from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission, MissionItem
from gcs.mavlink.mission_protocol import MISSION_TYPE_FENCE, MISSION_TYPE_RALLY, MissionClient
from gcs.mission.fence import (
    FencePlan,
    fence_items,
    rally_items,
    same_fence_item,
    same_rally_item,
)
from gcs.mission.geographic import derive_file
from tests.e2e.flying import online, register, wait_for
from tests.geographic import field, point, polygon, rectangle
from tests.service_process import ServiceProcess
from tests.sitl.ardupilot_sitl import homes_at_starts, instances
from tests.sitl.test_real_ardupilot import all_events, create_flight, final_state

pytestmark = [pytest.mark.sitl, pytest.mark.slow, pytest.mark.timeout(900)]

HOME = (-35.363262, 149.165237, 584.0)
ALT_M = 10.0
FENCE_HALF_M = 60.0
TARGET_EAST_M = 120.0
SPEEDUP = 5.0
BREACH_WAIT_S = 120.0  # wall seconds, a bound on a hang
AT_FENCE_M = 15.0
"""How far past the fence line the vehicle may be when ArduCopter has changed mode: it
checks at 25 Hz and the mode change brakes from cruise speed (WPNAV 10 m/s by default
gives about 10 m)."""


def lat_lon(east: float, north: float) -> tuple[float, float]:
    lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, HOME[0], HOME[1], 0.0)
    return (round(float(lat), 7), round(float(lon), 7))


def square(half: float) -> tuple[tuple[float, float], ...]:
    return tuple(
        lat_lon(e, n) for e, n in ((-half, -half), (half, -half), (half, half), (-half, half))
    )


FENCE = FencePlan(
    inclusion_polygons=(square(FENCE_HALF_M),),
    exclusion_polygons=(tuple(lat_lon(e, n) for e, n in ((-40, 20), (-20, 20), (-20, 40))),),
    exclusion_circles=((*lat_lon(0.0, -40.0), 8.0),),
    rally_points=(lat_lon(30.0, 30.0), (*lat_lon(-30.0, -20.0), 20.0)),
)


def mission_east() -> Mission:
    lat, lon = (round(v * 1e7) for v in HOME[:2])
    x, y = (round(v * 1e7) for v in lat_lon(TARGET_EAST_M, 0.0))
    items = (
        MissionItem(Command.NAV_WAYPOINT, Frame.GLOBAL, x=lat, y=lon, z=HOME[2]),
        MissionItem(Command.NAV_TAKEOFF, z=ALT_M, x=lat, y=lon),
        MissionItem(Command.NAV_WAYPOINT, x=x, y=y, z=ALT_M),
        MissionItem(Command.NAV_LAND, x=x, y=y),
    )
    return Mission(items, Autopilot.ARDUPILOT, HOME)


def east_of_home(link: VehicleLink) -> float:
    position = link.state.position
    assert position is not None
    east, _, _ = pymap3d.geodetic2enu(position.lat, position.lon, 0.0, HOME[0], HOME[1], 0.0)
    return float(east)


@pytest.mark.parametrize(("action", "mode"), [(1, "RTL"), (2, "LAND")])
async def test_real_arducopter_keeps_our_fence_and_breaches_to_the_configured_action(
    tmp_path: Path, action: int, mode: str
) -> None:
    with instances([HOME], tmp_path, speedup=SPEEDUP) as (instance,):
        link = await client.connect(
            instance.connection, settings=LinkSettings(connect_timeout_s=60.0)
        )
        try:
            await fly_across(link, action, mode)
        finally:
            await link.close()


async def fly_across(link: VehicleLink, action: int, mode: str) -> None:
    missions = MissionClient(link)
    geofence = GeoFence(FENCE, action)
    await upload_fence(missions, geofence, ALT_M)  # each read back and compared already
    fence = await missions.download(MISSION_TYPE_FENCE)
    sent = fence_items(FENCE)
    assert len(fence) == len(sent) and all(map(same_fence_item, sent, fence)), fence
    rally = await missions.download(MISSION_TYPE_RALLY)
    sent_rally = rally_items(FENCE, ALT_M)
    assert len(rally) == 2 and all(map(same_rally_item, sent_rally, rally)), rally
    print(f"\nfence read back: {len(fence)} items; rally: {[(r.x, r.y, r.z) for r in rally]}")
    await missions.upload(mission_east())
    await enable_fence(link, geofence)

    actions = FlightActions(
        link, CommandPolicy(), ReadinessPolicy(arm_timeout_s=300.0, climb_timeout_s=120.0)
    )
    await actions.arm_and_take_off(ALT_M)
    with link.subscribe(["STATUSTEXT", "FENCE_STATUS"]) as heard:
        await actions.start_mission()
        await link.wait_for(
            "HEARTBEAT",
            lambda hb: link.state.mode not in ("AUTO", "GUIDED", ""),
            BREACH_WAIT_S,
        )
        await link.wait_for("GLOBAL_POSITION_INT", None, 5.0)  # where it is now
        east = east_of_home(link)
        heard_now = heard.drain()
    print(f"mode {link.state.mode} at {east:.1f} m east of home (fence at {FENCE_HALF_M} m)")
    texts = [m.text.rstrip("\x00") for m in heard_now if m.get_type() == "STATUSTEXT"]
    statuses = [m for m in heard_now if m.get_type() == "FENCE_STATUS" and m.breach_status]
    assert link.state.mode == mode, (link.state.mode, texts)
    assert any("Polygon fence breached" in t for t in texts), texts
    after = texts[texts.index("Polygon fence breached") :]
    assert "Manual recovery started" in after, texts  # the mode change during a breach
    assert FENCE_HALF_M - 1.0 <= east <= FENCE_HALF_M + AT_FENCE_M, east
    print(f"texts: {texts}")
    print(f"FENCE_STATUS with a breach: {statuses[-1] if statuses else None}")
    if statuses:  # FENCE_STATUS streams with the extended status, when it is asked for
        assert statuses[-1].breach_type == mavlink2.FENCE_BREACH_BOUNDARY
        assert statuses[-1].breach_count >= 1


def test_the_service_flies_a_geographic_scenario_inside_its_fence(tmp_path: Path) -> None:
    """The whole product on real ArduCopter: a geographic scenario (a field, a barn, a
    rally point) posted, planned, bound, uploaded (its fence and rally points verified
    and the fence enabled with the service's default FENCE_ACTION) and flown round the
    barn to the goal with the fence in force, without a breach."""
    document = field(zones=[polygon(rectangle(120, 60, 180, 140), role="no-fly", name="barn")])
    document["features"].append(point(40, 170, role="rally", name="gate"))
    scenario = derive_file(document).scenario
    service = ServiceProcess(tmp_path / "data")
    with instances(homes_at_starts(scenario), tmp_path, SPEEDUP) as sitl:
        service.start()
        try:
            with service.client() as client:
                body = json.dumps(document).encode()
                created = client.post(
                    "/scenarios", content=body, headers={"Content-Type": "application/geo+json"}
                )
                assert created.status_code == 201, created.text
                sid = created.json()["id"]
                planned = client.post(f"/scenarios/{sid}/plans", json={"wait_s": 30}).json()
                ids = [register(client, i.connection) for i in sitl]
                made = create_flight(client, planned["id"], scenario, ids, None)
                assert made.status_code == 201, made.text
                flight = made.json()["id"]
                wait_for(lambda: all(online(client, v) for v in ids), 60, "vehicles online")
                uploaded = client.post(f"/flights/{flight}/upload")
                assert uploaded.status_code == 200, uploaded.text
                assert all(v["ok"] for v in uploaded.json()["vehicles"]), uploaded.text
                assert client.post(f"/flights/{flight}/start").status_code == 202
                state = final_state(client, flight)
                events = all_events(client, flight)
        finally:
            service.stop()
    kinds = [(e["kind"], e["uav_id"]) for e in events]
    print(f"\ngeographic service flight with its fence: {state['state']}; {kinds[-6:]}")
    assert state["state"] == "landed", (state, kinds[-20:])

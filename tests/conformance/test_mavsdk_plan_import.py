"""MAVSDK 4.1 (its bundled C++ library) reads our files into the items we wrote.

MAVSDK's importers need a System, and a System needs a vehicle: a pymavlink HEARTBEAT on
loopback (autopilot 3 or 12) is enough, nothing else is asked of it. What MAVSDK does
with our files, checked below:

- `.plan`: it ignores `firmwareType` and asks the connected autopilot. For ArduPilot it
  inserts `plannedHomePosition` as item 0 (NAV_WAYPOINT, frame 5 GLOBAL_INT, params 0,
  altitude AMSL), where we write frame 0 GLOBAL as QGC does: same place, other frame
  number, and ArduPilot overwrites item 0 on upload anyway. For PX4 it drops the home.
  It marks the first real item `current`.
- `.waypoints` (`import_mission_planner_mission`): it reads every line as an item, line 0
  too, so for PX4 our home line comes back as item 0 (do not upload that list to PX4
  as is); for ArduPilot it then inserts a copy of line 0 (frame 5) before it once more.
"""

from __future__ import annotations

import socket
import threading
from collections.abc import AsyncIterator, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

import mavsdk.asyncio as mavsdk  # the test extra installs it: a missing one must fail
import pytest
from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
from pymavlink import mavutil

from gcs.mavlink.mission_item import Autopilot, Frame, Mission, MissionItem
from gcs.mission.build import build_missions
from gcs.mission.fence import fence_items, fence_of, rally_items
from gcs.mission.files import plan_text, write_plan, write_waypoints
from gcs.mission.geographic import load_geographic
from planner.cases import load_case
from planner.pipeline import PlannerSettings, plan
from tests.geographic import EXAMPLE

GLOBAL_INT = 5
MAV_TYPE_QUADROTOR = 2
MAV_STATE_STANDBY = 3


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@contextmanager
def heartbeats(port: int, autopilot: Autopilot) -> Iterator[None]:
    """A stand-in vehicle: HEARTBEAT at 10 Hz to MAVSDK's port until the block ends."""
    vehicle = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{port}", source_system=1, source_component=1
    )
    stop = threading.Event()

    def beat() -> None:
        while not stop.is_set():
            vehicle.mav.heartbeat_send(MAV_TYPE_QUADROTOR, int(autopilot), 0, 0, MAV_STATE_STANDBY)
            stop.wait(0.1)

    thread = threading.Thread(target=beat, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
        vehicle.close()


@dataclass(frozen=True)
class Importer:
    autopilot: Autopilot
    plugin: MissionRawAsync


@pytest.fixture(params=list(Autopilot), ids=lambda a: a.name)
async def importer(request: pytest.FixtureRequest) -> AsyncIterator[Importer]:
    """MAVSDK's raw-mission plugin, connected to a vehicle of the given autopilot."""
    autopilot: Autopilot = request.param
    port = free_udp_port()
    config = mavsdk.Configuration.create_with_component_type(mavsdk.ComponentType.GROUND_STATION)
    async with mavsdk.Mavsdk(config) as sdk:
        await sdk.add_any_connection(f"udpin://127.0.0.1:{port}")
        with heartbeats(port, autopilot):
            system = await sdk.first_autopilot(timeout_s=5.0)
            assert system is not None, "MAVSDK did not see the stand-in vehicle"
            expected = {Autopilot.ARDUPILOT: 2, Autopilot.PX4: 1}[autopilot]  # MAVSDK's enum
            assert int(await system.autopilot_type()) == expected
            yield Importer(autopilot, MissionRawAsync(system))


@pytest.fixture(scope="module")
def case_6() -> dict[Autopilot, list[Mission]]:
    scenario = load_case("case-6")
    result = plan(scenario, PlannerSettings(population=10, iterations=20))
    return {a: list(build_missions(result, scenario, a).values()) for a in Autopilot}


def ours(item) -> MissionItem:
    """MAVSDK's MissionItem as ours, to compare with `same_as` (float32, NaN == NaN)."""
    return MissionItem(
        item.command,
        item.frame,
        (item.param1, item.param2, item.param3, item.param4),
        item.x,
        item.y,
        item.z,
        bool(item.autocontinue),
    )


async def test_mavsdk_imports_our_plan(
    importer: Importer, case_6: dict[Autopilot, list[Mission]], tmp_path: Path
) -> None:
    for k, mission in enumerate(case_6[importer.autopilot]):
        path = tmp_path / f"{k}.plan"
        write_plan(mission, path)
        imported = (await importer.plugin.import_qgroundcontrol_mission(str(path))).mission_items
        assert [i.seq for i in imported] == list(range(len(mission.items)))
        theirs = [ours(i) for i in imported]
        start = 0
        if importer.autopilot == Autopilot.ARDUPILOT:
            start, home, mine = 1, theirs[0], mission.items[0]
            assert (home.frame, mine.frame) == (GLOBAL_INT, Frame.GLOBAL)
            assert home.same_as(MissionItem(16, GLOBAL_INT, (0.0,) * 4, mine.x, mine.y, mine.z))
        assert [i.current for i in imported[start:]] == [1] + [0] * (len(imported) - start - 1)
        for a, b in zip(mission.items[start:], theirs[start:], strict=True):
            assert a.same_as(b), (a, b)


async def test_mavsdk_reads_every_line_of_our_waypoints(
    importer: Importer, case_6: dict[Autopilot, list[Mission]], tmp_path: Path
) -> None:
    mission = case_6[importer.autopilot][0]
    path = tmp_path / "m.waypoints"
    write_waypoints(mission, path)
    imported = (await importer.plugin.import_mission_planner_mission(str(path))).mission_items
    theirs = [ours(i) for i in imported]
    if importer.autopilot == Autopilot.ARDUPILOT:
        copy, *lines = theirs  # MAVSDK's extra copy of line 0, in frame 5 GLOBAL_INT
        assert copy.frame == GLOBAL_INT
        assert copy.same_as(
            MissionItem(16, GLOBAL_INT, (0.0,) * 4, lines[0].x, lines[0].y, lines[0].z)
        )
    else:
        home, *lines = theirs  # our line 0, read as an item
        assert (home.frame, home.command) == (Frame.GLOBAL, 16)
        assert (home.lat, home.lon, home.z) == pytest.approx(mission.home, abs=1e-7)
    assert len(lines) == len(mission.items)
    assert all(a.same_as(b) for a, b in zip(mission.items, lines, strict=True))


async def test_mavsdk_rejects_a_plan_without_a_mission(importer: Importer, tmp_path: Path) -> None:
    path = tmp_path / "bad.plan"
    path.write_text('{"fileType": "Plan", "version": 1}')
    with pytest.raises(mavsdk.MavsdkError, match=r"(?i)parse"):
        await importer.plugin.import_qgroundcontrol_mission(str(path))


async def test_mavsdk_imports_the_fence_and_rally_points_of_our_plan(
    importer: Importer, case_6: dict[Autopilot, list[Mission]], tmp_path: Path
) -> None:
    """A geographic scenario's `.plan`: MAVSDK reads its `geoFence` and `rallyPoints` into
    the FENCE and RALLY items our flights upload (issue 26, item 2)."""
    fence = fence_of(load_geographic(EXAMPLE.read_text()))
    fence = replace(fence, rally_points=((-35.3631, 149.1653), (-35.3629, 149.1656, 25.0)))
    assert fence.inclusion_polygons and fence.exclusion_polygons and fence.exclusion_circles
    path = tmp_path / "fenced.plan"
    path.write_text(plan_text(case_6[importer.autopilot][0], fence=fence, rally_alt_m=15.0))
    imported = await importer.plugin.import_qgroundcontrol_mission(str(path))
    for theirs, sent in (
        (imported.geofence_items, fence_items(fence)),
        (imported.rally_items, rally_items(fence, default_alt_m=15.0)),
    ):
        assert len(theirs) == len(sent)
        for a, b in zip(theirs, sent, strict=True):
            assert (a.command, a.x, a.y) == (b.command, b.x, b.y)
            assert (a.param1, a.z) == pytest.approx((b.params[0], b.z), abs=1e-3)

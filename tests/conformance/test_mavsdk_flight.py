"""MAVSDK 4.1 (PyPI, its bundled C++ library) against the simulated vehicles, over real
loopback sockets: connect, telemetry, mission_raw upload/download/clear, arm, fly a
mission to the end, and return to launch or land mid-flight, in both flavours.

A behaviour MAVSDK rejects is a bug in the mock. The ArduPilot flavour is reached over
TCP and the PX4 flavour over UDP, as their SITLs are; the connection test crosses both.
MAVSDK's URLs are `udpout://host:port` and `tcpout://host:port`. For ArduPilot the
telemetry rates are set first (it streams nothing until asked), uploads wait for the end
of the boot (ArduCopter answers NO_SPACE until "ArduPilot Ready"), the mission starts with
a home item (mission_raw sends items as given; ArduPilot's item 0 is home), a download
returns what ArduPilot stores (frame 3 for 6, NAV_LAND param4 1), arming and starting are
retried together (arming in STABILIZE works before AUTO does), and the end of a flight is
landed and disarmed (ArduCopter reports no NAV_LAND and rewinds the mission to item 1).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import AsyncGenerator, AsyncIterator, Awaitable, Callable
from dataclasses import dataclass
from typing import TypeVar

import mavsdk.asyncio as mavsdk  # the test extra installs it: a missing one must fail
import pymap3d
import pytest
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
from mavsdk.asyncio.plugins.param import ParamAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.mission_raw import MissionItem
from mavsdk.plugins.telemetry import FlightMode

from sitl_mock import Simulator, VehicleConfig
from sitl_mock.codec import mavlink

T = TypeVar("T")

HOME = (47.397742, 8.545594, 488.0)
SPEEDUP = 25.0
ALT_M = 10.0
LEG_M = 30.0
WAYPOINTS_EN = [(0.0, LEG_M), (LEG_M, LEG_M), (LEG_M, 0.0)]
ARRIVAL_M = 3.0
LAND_DRIFT_M = 8.0
TELEMETRY_HZ = 10.0
WAIT_S = 20.0
READY_S = 60.0
"""Wall seconds to become armable in AUTO: ArduCopter's 41.5 s at 25x is under 2 s, but a
loaded machine slows the simulation (it slips, as real SITL does): these are bounds on a
hang, not expectations."""
FLIGHT_S = 90.0

GLOBAL, GLOBAL_RELATIVE_ALT_INT = 0, 6
NAV_WAYPOINT, NAV_LAND, NAV_TAKEOFF = 16, 21, 22
AUTOPILOT_ENUM = {"ardupilot": 2, "px4": 1}  # MAVSDK's Autopilot values
BOOT_MODE = {"ardupilot": FlightMode.STABILIZED, "px4": FlightMode.POSCTL}
TRANSPORT = {"ardupilot": "tcp", "px4": "udp"}


@dataclass(frozen=True)
class Vehicle:
    """One simulated vehicle and MAVSDK's plugins connected to it."""

    autopilot: str
    sim: Simulator
    system: mavsdk.System
    telemetry: TelemetryAsync
    mission: MissionRawAsync
    action: ActionAsync


def mavsdk_url(connection_string: str) -> str:
    """The mock's pymavlink string as a MAVSDK URL: udpout:h:p -> udpout://h:p, tcp -> tcpout."""
    kind, host, port = connection_string.split(":")
    return f"{'udpout' if kind == 'udpout' else 'tcpout'}://{host}:{port}"


async def connect(sim: Simulator, sdk: mavsdk.Mavsdk, autopilot: str) -> Vehicle:
    await sdk.add_any_connection(mavsdk_url(sim.connection_string(1)))
    system = await sdk.first_autopilot(timeout_s=WAIT_S)
    assert system is not None, "MAVSDK did not discover the simulated vehicle"
    booted = lambda: sim.state(1).system_status != mavlink.MAV_STATE_BOOT  # noqa: E731
    assert await asyncio.to_thread(sim.wait_until, booted, WAIT_S)
    telemetry = TelemetryAsync(system)
    if autopilot == "ardupilot":  # streams nothing until asked, as ArduCopter
        for set_rate in (
            telemetry.set_rate_position,
            telemetry.set_rate_in_air,
            telemetry.set_rate_landed_state,
            telemetry.set_rate_home,
            telemetry.set_rate_health,
        ):
            await set_rate(TELEMETRY_HZ)
    return Vehicle(autopilot, sim, system, telemetry, MissionRawAsync(system), ActionAsync(system))


@contextlib.asynccontextmanager
async def simulated(autopilot: str, transport: str) -> AsyncIterator[Vehicle]:
    """A one-vehicle simulator and a MAVSDK ground station connected to it."""
    config = VehicleConfig(sysid=1, home=HOME, autopilot=autopilot, transport=transport)
    sim = Simulator([config], speedup=SPEEDUP, seed=0)
    with sim.running():
        sdk_config = mavsdk.Configuration.create_with_component_type(
            mavsdk.ComponentType.GROUND_STATION
        )
        async with mavsdk.Mavsdk(sdk_config) as sdk:
            yield await connect(sim, sdk, autopilot)


@pytest.fixture(params=["ardupilot", "px4"])
async def vehicle(request: pytest.FixtureRequest) -> AsyncIterator[Vehicle]:
    async with simulated(request.param, TRANSPORT[request.param]) as connected:
        yield connected


async def first(
    stream: AsyncGenerator[T, None],
    accept: Callable[[T], bool] = lambda _: True,
    timeout: float = WAIT_S,
) -> T:
    """The first value of a MAVSDK subscription that `accept`s, within `timeout` seconds."""
    async with contextlib.aclosing(stream), asyncio.timeout(timeout):
        async for value in stream:
            if accept(value):
                return value
    raise AssertionError("the subscription ended")


async def retry(call: Callable[[], Awaitable[T]], timeout: float = WAIT_S) -> T:
    """`call` until it stops raising a MavsdkError, starting attempts for `timeout` seconds.

    A blocking MAVSDK call is never cancelled: MAVSDK bounds it itself, while a cancelled one
    keeps its executor thread, which never returns once the Mavsdk is destroyed and then
    hangs the event loop's shutdown instead of failing the test.
    """
    deadline = asyncio.get_running_loop().time() + timeout
    while True:
        try:
            return await call()
        except mavsdk.MavsdkError:
            if asyncio.get_running_loop().time() > deadline:
                raise
            await asyncio.sleep(0.05)


# -- missions ---------------------------------------------------------------------------------


def waypoint_e7(east: float, north: float) -> tuple[int, int]:
    lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, *HOME)
    return round(lat * 1e7), round(lon * 1e7)


def item(
    seq: int,
    command: int,
    frame: int = GLOBAL_RELATIVE_ALT_INT,
    x: int = 0,
    y: int = 0,
    z: float = ALT_M,
) -> MissionItem:
    return MissionItem(
        seq=seq, frame=frame, command=command, current=int(seq == 0), autocontinue=1, x=x, y=y, z=z
    )


def square_mission(autopilot: str) -> list[MissionItem]:
    """[Home,] take-off, three corners, land where it stops (seq numbered from 0)."""
    home_x, home_y = round(HOME[0] * 1e7), round(HOME[1] * 1e7)
    commands: list[tuple] = [(NAV_WAYPOINT, GLOBAL, home_x, home_y, HOME[2])] * (
        autopilot == "ardupilot"
    )
    commands.append((NAV_TAKEOFF, GLOBAL_RELATIVE_ALT_INT, 0, 0, ALT_M))
    commands += [
        (NAV_WAYPOINT, GLOBAL_RELATIVE_ALT_INT, *waypoint_e7(e, n), ALT_M) for e, n in WAYPOINTS_EN
    ]
    commands.append((NAV_LAND, GLOBAL_RELATIVE_ALT_INT, 0, 0, 0.0))
    return [
        item(seq, command, frame, x, y, z) for seq, (command, frame, x, y, z) in enumerate(commands)
    ]


def as_stored(autopilot: str, mission: list[MissionItem]) -> list[MissionItem]:
    """What the autopilot gives back: ArduCopter SITL returned frame 3 for 6 and param4 1 for
    NAV_LAND (docs/sitl_mock.md, wire facts); PX4 keeps what it was sent."""
    if autopilot != "ardupilot":
        return mission
    stored = []
    for sent in mission:
        frame = 3 if sent.frame == GLOBAL_RELATIVE_ALT_INT else sent.frame
        param4 = 1.0 if sent.command == NAV_LAND else sent.param4
        stored.append(
            MissionItem(
                seq=sent.seq,
                frame=frame,
                command=sent.command,
                current=sent.current,
                autocontinue=sent.autocontinue,
                param1=sent.param1,
                param2=sent.param2,
                param3=sent.param3,
                param4=param4,
                x=sent.x,
                y=sent.y,
                z=sent.z,
                mission_type=sent.mission_type,
            )
        )
    return stored


def as_tuple(mission_item: MissionItem) -> tuple:
    """What must survive a round trip (float32 params and z, NaN-safe)."""
    floats = (
        mission_item.param1,
        mission_item.param2,
        mission_item.param3,
        mission_item.param4,
        mission_item.z,
    )
    return (
        mission_item.seq,
        mission_item.frame,
        mission_item.command,
        mission_item.autocontinue,
        mission_item.x,
        mission_item.y,
        *("nan" if math.isnan(f) else round(f, 3) for f in floats),
    )


def distance_m(lat: float, lon: float, east: float, north: float) -> float:
    e, n, _ = pymap3d.geodetic2enu(lat, lon, HOME[2], *HOME)
    return math.hypot(e - east, n - north)


# -- tests ------------------------------------------------------------------------------------


@pytest.mark.parametrize("transport", ["udp", "tcp"])
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
async def test_connects_and_reads_telemetry(autopilot: str, transport: str) -> None:
    """Discovery, autopilot type, boot flight mode, position and home at HOME, health flags
    that turn true once the position estimate is ready, disarmed on the ground."""
    async with simulated(autopilot, transport) as v:
        assert int(await v.system.autopilot_type()) == AUTOPILOT_ENUM[autopilot]
        assert await first(v.telemetry.subscribe_flight_mode()) == BOOT_MODE[autopilot]
        position = await first(v.telemetry.subscribe_position(), lambda p: p.latitude_deg != 0.0)
        assert (position.latitude_deg, position.longitude_deg) == pytest.approx(HOME[:2], abs=1e-6)
        assert position.absolute_altitude_m == pytest.approx(HOME[2], abs=0.5)
        assert position.relative_altitude_m == pytest.approx(0.0, abs=0.5)
        await first(v.telemetry.subscribe_health(), lambda h: all(vars(h).values()))
        assert await v.telemetry.health_all_ok()
        home = await first(v.telemetry.subscribe_home())
        assert (home.latitude_deg, home.longitude_deg) == pytest.approx(HOME[:2], abs=1e-6)
        assert await first(v.telemetry.subscribe_armed()) is False
        assert await first(v.telemetry.subscribe_in_air()) is False


async def test_mission_upload_download_clear(vehicle: Vehicle) -> None:
    """mission_raw uploads the square, downloads it item by item unchanged, and clears it."""
    sent = square_mission(vehicle.autopilot)
    await vehicle.mission.upload_mission(sent)
    received = await vehicle.mission.download_mission()
    assert [as_tuple(i) for i in received] == [
        as_tuple(i) for i in as_stored(vehicle.autopilot, sent)
    ]
    assert vehicle.sim.mission(1)[-1].command == NAV_LAND
    await vehicle.mission.clear_mission()
    left = await vehicle.mission.download_mission()
    home_only = 1 if vehicle.autopilot == "ardupilot" else 0  # ArduPilot keeps home as item 0
    assert len(left) == home_only
    assert len(vehicle.sim.mission(1)) == home_only


async def arm_and_start(vehicle: Vehicle) -> None:
    """Arm and start the mission, both retried until both work: ArduCopter arms in STABILIZE
    before its position estimate allows AUTO.

    Auto-disarm goes off first. At 25x an armed vehicle idle on the ground disarms 0.4 wall
    seconds after arming (10 s), which a loaded machine can spend between the two calls; the
    start then puts a disarmed vehicle in AUTO (ArduCopter accepts MISSION_START disarmed),
    and it never flies."""
    params = ParamAsync(vehicle.system)
    if vehicle.autopilot == "ardupilot":
        await retry(lambda: params.set_param_int("DISARM_DELAY", 0))
    else:
        await retry(lambda: params.set_param_float("COM_DISARM_PRFLT", -1.0))

    async def attempt() -> None:
        await vehicle.action.arm()
        await vehicle.mission.start_mission()

    await retry(attempt, READY_S)


async def follow_to_end(vehicle: Vehicle, total: int) -> list[int]:
    """Every `current` MAVSDK reports until its mark of the end: `total` (PX4), or (ArduPilot,
    which rewinds on disarming) back to the take-off after the landing item."""
    seen: list[int] = []
    progress = vehicle.mission.subscribe_mission_progress()
    async with contextlib.aclosing(progress), asyncio.timeout(FLIGHT_S + READY_S):
        async for update in progress:
            assert update.total == total, update
            seen.append(update.current)
            if update.current == total or (seen[:-1] and update.current < max(seen)):
                return seen
    raise AssertionError(f"progress ended early at {seen}")


async def landed_and_disarmed(vehicle: Vehicle) -> None:
    await first(vehicle.telemetry.subscribe_in_air(), lambda in_air: not in_air, FLIGHT_S)
    await first(vehicle.telemetry.subscribe_armed(), lambda armed: not armed, WAIT_S)


async def test_flies_the_mission_to_the_end(vehicle: Vehicle) -> None:
    """Upload, arm, start_mission, mission progress to the end, landed and disarmed where the
    last waypoint is; the simulator's own track confirms it."""
    mission = square_mission(vehicle.autopilot)
    await vehicle.mission.upload_mission(mission)
    following = asyncio.create_task(follow_to_end(vehicle, len(mission)))
    try:
        await arm_and_start(vehicle)
        assert await first(
            vehicle.telemetry.subscribe_flight_mode(), lambda mode: mode == FlightMode.MISSION
        )
        seen = await following
    finally:
        following.cancel()
    await landed_and_disarmed(vehicle)
    if vehicle.autopilot == "ardupilot":
        *flown, rewound = seen
        assert flown == sorted(flown) and flown[-1] == len(mission) - 1 and rewound == 1, seen
        assert not await vehicle.mission.is_mission_finished()  # it holds item 1 again
    else:
        assert seen == sorted(seen), seen
        assert await vehicle.mission.is_mission_finished()
    track = vehicle.sim.track(1)
    assert max(p.alt for p in track) == pytest.approx(ALT_M, abs=1.0)
    end = track[-1]
    assert not end.armed and end.alt == pytest.approx(0.0, abs=0.1)
    assert distance_m(end.lat, end.lon, *WAYPOINTS_EN[-1]) < ARRIVAL_M
    for east, north in WAYPOINTS_EN:
        assert min(distance_m(p.lat, p.lon, east, north) for p in track) < ARRIVAL_M


@pytest.mark.parametrize("command", ["return_to_launch", "land"])
async def test_leaves_the_mission_mid_flight(vehicle: Vehicle, command: str) -> None:
    """action.return_to_launch (lands at home) or action.land (lands where it is) after the
    first corner: the flight mode follows, and it lands and disarms there."""
    await vehicle.mission.upload_mission(square_mission(vehicle.autopilot))
    first_corner = 2 if vehicle.autopilot == "ardupilot" else 1
    await arm_and_start(vehicle)
    await first(
        vehicle.mission.subscribe_mission_progress(),
        lambda p: p.current > first_corner,
        FLIGHT_S + READY_S,
    )
    await getattr(vehicle.action, command)()
    there = vehicle.sim.state(1)
    mode = FlightMode.RETURN_TO_LAUNCH if command == "return_to_launch" else FlightMode.LAND
    assert await first(vehicle.telemetry.subscribe_flight_mode(), lambda m: m == mode)
    await landed_and_disarmed(vehicle)
    end = vehicle.sim.track(1)[-1]
    if command == "return_to_launch":
        assert distance_m(end.lat, end.lon, 0.0, 0.0) < ARRIVAL_M
    else:
        e, n, _ = pymap3d.geodetic2enu(there.lat, there.lon, HOME[2], *HOME)
        assert distance_m(end.lat, end.lon, e, n) < LAND_DRIFT_M
        assert distance_m(end.lat, end.lon, 0.0, 0.0) > LEG_M / 2

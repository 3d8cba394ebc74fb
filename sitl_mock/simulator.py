"""Runs N vehicles in one asyncio loop: fixed physics steps on simulated time, the ports,
and the truth (tracks, separation). Usable from a test thread or inside a running loop.

Vehicle behaviour runs on the simulated clock (`speedup` times the loop's time, in fixed
steps); link-protocol timers run on `wall_clock` (the running loop's clock unless a test
injects another). On a `VirtualTimeLoop`, with in-memory ports (`transport="memory"`),
the vehicles and the ground station share one virtual clock: a flight replays exactly."""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TypeVar

import numpy as np

from .clock import DEFAULT_STEP_S, SimClock, loop_time
from .faults import Faults
from .flight import AIRBORNE_ABOVE_M
from .geo import LocalFrame
from .kinematics import PointMassFleet
from .mission_item import MissionItem
from .snapshot import VehicleState
from .track import Separation, SeparationMonitor, TrackPoint, TrackRecorder
from .transport import (
    MemoryPort,
    MemoryServer,
    UdpOutput,
    connection_string,
    open_endpoint,
    parse_output,
)
from .vehicle import Vehicle, VehicleConfig

T = TypeVar("T")

TRACK_RATE_HZ = 10.0
CALL_TIMEOUT_S = 10.0
MIN_SLEEP_S = 0.001
MEMORY_BASE_PORT = 5760
"""Nominal ports of in-memory vehicles with no port of their own: 5760 + 10 (i - 1), as SITL."""


class Simulator:
    """N vehicles, one loop, one clock. See the package docstring for an example."""

    def __init__(
        self,
        vehicles: Sequence[VehicleConfig],
        speedup: float = 1.0,
        seed: int = 0,
        host: str = "127.0.0.1",
        stream_by_default: bool = False,
        step_s: float = DEFAULT_STEP_S,
        track_log: Path | str | None = None,
        wall_clock: Callable[[], float] = loop_time,
    ) -> None:
        sysids = [config.sysid for config in vehicles]
        if not sysids:
            raise ValueError("at least one vehicle is needed")
        if len(set(sysids)) != len(sysids):
            raise ValueError(f"system ids must be unique, got {sysids}")
        self.host = host
        self._clock = SimClock(speedup, step_s)
        lat, lon, alt = vehicles[0].home
        self._frame = LocalFrame(lat, lon, alt)
        homes_en = np.array([self._frame.to_local(c.home[0], c.home[1]) for c in vehicles])
        self._fleet = PointMassFleet(homes_en)
        self._geo_step = -1
        self._lat = self._lon = np.zeros(len(vehicles))
        rngs = np.random.default_rng(seed).spawn(len(vehicles))
        self._vehicles = {
            config.sysid: Vehicle(
                config,
                self._fleet.body(i),
                tuple(homes_en[i]),
                self._frame.to_local,
                self._geodetic_of,
                lambda: self.sim_time,
                rngs[i],
                stream_by_default,
                wall_clock,
            )
            for i, config in enumerate(vehicles)
        }
        self._track = TrackRecorder(sysids, Path(track_log) if track_log else None)
        self._separation = SeparationMonitor(sysids)
        self._track_every = max(1, round(1.0 / (TRACK_RATE_HZ * step_s)))
        self._loop: asyncio.AbstractEventLoop | None = None
        self._loop_thread: int | None = None
        self._task: asyncio.Task[None] | None = None
        self._thread: threading.Thread | None = None
        self._stopping = False
        self._outputs: dict[tuple[str, int], UdpOutput] = {}

    # -- life cycle ----------------------------------------------------------------------

    async def start(self) -> None:
        """Open every vehicle's socket and start stepping (inside the running loop)."""
        self._loop = asyncio.get_running_loop()
        self._loop_thread = threading.get_ident()
        for index, vehicle in enumerate(self._vehicles.values()):
            config = vehicle.config
            port = config.port
            if config.transport == "memory" and not port:
                port = MEMORY_BASE_PORT + 10 * index
            vehicle.endpoint = await open_endpoint(
                config.transport, self.host, port, vehicle.on_packet
            )
            vehicle.outputs = [await self._output(text, vehicle) for text in config.outputs]
        self._stopping = False
        self._clock.start()
        self._task = asyncio.create_task(self._run())

    async def stop(self) -> None:
        self._stopping = True
        if self._task is not None:
            await asyncio.wait_for(self._task, timeout=CALL_TIMEOUT_S)
            self._task = None
        for vehicle in self._vehicles.values():
            if vehicle.endpoint is not None:
                await vehicle.endpoint.close()
        for output in self._outputs.values():
            await output.close()
        self._outputs.clear()
        self._track.close()

    async def _output(self, text: str, vehicle: Vehicle) -> UdpOutput:
        """The one socket for a `udp:HOST:PORT` output, opened by the first vehicle naming it."""
        address = parse_output(text)
        output = self._outputs.get(address)
        if output is None:
            output = self._outputs[address] = await UdpOutput.open(*address)
        output.subscribe(vehicle.on_packet)
        return output

    @contextlib.contextmanager
    def running(self) -> Iterator[Simulator]:
        """Run in a background thread with its own loop; stop and join on exit."""
        started = threading.Event()
        failure: list[BaseException] = []

        async def main() -> None:
            try:
                await self.start()
            except BaseException as exc:
                failure.append(exc)
                started.set()
                raise
            started.set()
            while not self._stopping:
                await asyncio.sleep(0.05)
            await self.stop()

        self._thread = threading.Thread(
            target=asyncio.run, args=(main(),), daemon=True, name="sitl_mock"
        )
        self._thread.start()
        if not started.wait(timeout=CALL_TIMEOUT_S) or failure:
            self._stopping = True
            raise RuntimeError(f"simulator failed to start: {failure}")
        try:
            yield self
        finally:
            self._stopping = True
            self._thread.join(timeout=CALL_TIMEOUT_S)
            self._thread = None

    async def _run(self) -> None:
        while not self._stopping:
            for _ in range(self._clock.steps_due()):
                self._step()
            await asyncio.sleep(max(MIN_SLEEP_S, self._clock.wall_until_next_step()))

    def _step(self) -> None:
        now = self._clock.advance()
        for vehicle in self._vehicles.values():
            vehicle.step(now)
        self._fleet.step(self._clock.step_s)
        pos = self._fleet.pos
        self._separation.update(now, pos[:, :2], pos[:, 2] > AIRBORNE_ABOVE_M)
        if self._clock.steps % self._track_every == 0:
            lat, lon = self._geodetic()
            armed = np.array([v.flight.armed for v in self._vehicles.values()])
            self._track.record(now, lat, lon, pos[:, 2].copy(), armed)

    def _geodetic(self) -> tuple[np.ndarray, np.ndarray]:
        """Every vehicle's lat/lon, converted once per step at most."""
        if self._geo_step != self._clock.steps:
            self._lat, self._lon = self._frame.to_geodetic(
                self._fleet.pos[:, 0], self._fleet.pos[:, 1]
            )
            self._geo_step = self._clock.steps
        return self._lat, self._lon

    def _geodetic_of(self, index: int) -> tuple[float, float]:
        lat, lon = self._geodetic()
        return float(lat[index]), float(lon[index])

    # -- the API (safe from any thread) --------------------------------------------------

    @property
    def sim_time(self) -> float:
        return self._clock.now

    @property
    def sysids(self) -> list[int]:
        return list(self._vehicles)

    def ports(self) -> list[int]:
        """Every vehicle's port (nominal for in-memory vehicles), once running."""
        return [v.endpoint.port for v in self._vehicles.values() if v.endpoint is not None]

    def port(self, sysid: int) -> int:
        endpoint = self._vehicle(sysid).endpoint
        if endpoint is None:
            raise RuntimeError("the simulator is not running")
        return endpoint.port

    def connection_string(self, sysid: int) -> str:
        """How a pymavlink client reaches the vehicle's own server (`udpout:` or `tcp:`)."""
        return connection_string(self._vehicle(sysid).config.transport, self.host, self.port(sysid))

    def memory_port(self, sysid: int) -> MemoryPort:
        """A new in-memory connection to a `transport="memory"` vehicle (on the loop)."""
        endpoint = self._vehicle(sysid).endpoint
        if not isinstance(endpoint, MemoryServer):
            raise RuntimeError(f"vehicle {sysid} has no in-memory port (is it running?)")
        return endpoint.connect()

    def memory_port_at(self, port: int) -> MemoryPort:
        """A new in-memory connection to the vehicle serving nominal `port`;
        ConnectionRefusedError if none does, as a TCP connect would be refused."""
        for vehicle in self._vehicles.values():
            endpoint = vehicle.endpoint
            if isinstance(endpoint, MemoryServer) and endpoint.port == port:
                return endpoint.connect()
        raise ConnectionRefusedError(f"no simulated vehicle serves port {port}")

    def output_addresses(self) -> list[tuple[str, int]]:
        """Every `--out` ground-station address the vehicles send to."""
        return sorted(
            {parse_output(text) for v in self._vehicles.values() for text in v.config.outputs}
        )

    def rejected_packets(self, sysid: int) -> int:
        """Packets a signing vehicle dropped (unsigned or signed with another key)."""
        return self._call(lambda: self._vehicle(sysid).rejected_packets)

    def set_faults(self, sysid: int, faults: Faults) -> None:
        self._call(self._vehicle(sysid).set_faults, faults)

    def silence(self, sysid: int, seconds: float) -> None:
        """The link drops everything, both ways, for `seconds` of simulated time."""
        self._call(self._vehicle(sysid).silence, seconds)

    def reboot(self, sysid: int) -> None:
        self._call(self._vehicle(sysid).reboot)

    def state(self, sysid: int) -> VehicleState:
        return self._call(self._vehicle(sysid).state)

    def local_positions(self) -> dict[int, tuple[float, float, float]]:
        """Every vehicle's east and north metres in the fleet's frame and its height above
        home: the simulator's truth, without a geodetic conversion (cheap to poll)."""

        def positions() -> dict[int, tuple[float, float, float]]:
            pos = self._fleet.pos.tolist()
            return {
                sysid: (pos[k][0], pos[k][1], pos[k][2]) for k, sysid in enumerate(self._vehicles)
            }

        return self._call(positions)

    def to_local(self, lat: float, lon: float) -> tuple[float, float]:
        """A place in the frame of `local_positions` (east, north metres)."""
        return self._frame.to_local(lat, lon)

    def mission(self, sysid: int, mission_type: int = 0) -> list[MissionItem]:
        return self._call(self._vehicle(sysid).mission, mission_type)

    def load_mission(self, sysid: int, items: list[MissionItem], mission_type: int = 0) -> None:
        """Give a vehicle a mission without the protocol (ArduPilot: item 0 is home)."""
        self._call(self._vehicle(sysid).store.load, items, mission_type)

    def advance(self, seconds: float) -> None:
        """Step simulated time by hand, without sockets or wall clock (not while running)."""
        if self._task is not None:
            raise RuntimeError("advance() steps a simulator that is not running")
        for _ in range(round(seconds / self._clock.step_s)):
            self._step()

    def set_param(self, sysid: int, name: str, value: float) -> None:
        vehicle = self._vehicle(sysid)

        def set_and_apply() -> None:
            vehicle.params.set(name, value)
            vehicle.flight.apply_limits()

        self._call(set_and_apply)

    def track(self, sysid: int) -> list[TrackPoint]:
        return self._call(self._track.track, sysid)

    def final_position(self, sysid: int) -> TrackPoint | None:
        return self._call(self._track.final, sysid)

    def min_separation(self) -> Separation | None:
        return self._call(self._separation.result, self._frame.to_geodetic)

    def wait_until(
        self, predicate: Callable[[], bool], timeout: float, poll_s: float = 0.02
    ) -> bool:
        """Poll `predicate` (from a non-loop thread) for up to `timeout` wall seconds."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return True
            time.sleep(poll_s)
        return bool(predicate())

    def vehicle(self, sysid: int) -> Vehicle:
        """The vehicle object itself, for callers on the simulator's loop."""
        return self._vehicle(sysid)

    def _vehicle(self, sysid: int) -> Vehicle:
        try:
            return self._vehicles[sysid]
        except KeyError:
            raise KeyError(f"no vehicle with system id {sysid}") from None

    def _call(self, fn: Callable[..., T], *args: object) -> T:
        """Run `fn` on the simulator's loop thread and wait for its result."""
        loop = self._loop
        if (
            loop is None
            or not loop.is_running()
            or self._loop_thread == threading.get_ident()
            or self._task is None
        ):
            return fn(*args)
        future: concurrent.futures.Future[T] = concurrent.futures.Future()

        def run() -> None:
            try:
                future.set_result(fn(*args))
            except BaseException as exc:
                future.set_exception(exc)

        loop.call_soon_threadsafe(run)
        return future.result(timeout=CALL_TIMEOUT_S)

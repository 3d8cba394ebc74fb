"""Simulated vehicles reachable in memory: what the in-process service connects to."""

from __future__ import annotations

from typing import Any

from gcs.mavlink.endpoint import Endpoint
from gcs.mavlink.errors import LinkError
from gcs.mavlink.transport import ByteTransport, MemoryTransport
from gcs.mission.geodesy import GridFrame
from planner.model.scenario import Scenario
from sitl_mock import Faults, Simulator, VehicleConfig

FAST_BOOT: dict[str, Any] = {"estimate_delay_s": 6.0, "position_delay_s": 3.0}
"""ArduCopter's boot squeezed (41.5 s to arm at speed-up 1 on real SITL): the tests that
are about the boot say so; the rest need not wait for it, even in virtual time."""


def configs_at_starts(
    scenario: Scenario, faults: Faults | None = None, **config: Any
) -> list[VehicleConfig]:
    """One in-memory vehicle per UAV, at its start cell, on SITL's nominal ports."""
    frame = GridFrame.of(scenario)
    configs = []
    for sysid, uav in enumerate(scenario.uavs, start=1):
        lat, lon = frame.to_geodetic(*uav.start)
        configs.append(
            VehicleConfig(
                sysid=sysid,
                home=(float(lat), float(lon), frame.alt0),
                transport="memory",
                faults=faults or Faults(),
                **{**FAST_BOOT, **config},
            )
        )
    return configs


class SimulatedVehicles:
    """Every simulator a test starts; `open` is the service's transport opener."""

    def __init__(self) -> None:
        self.simulators: list[Simulator] = []

    async def start(self, configs: list[VehicleConfig], seed: int = 1) -> Simulator:
        used = {port for sim in self.simulators for port in sim.ports()}
        base = max(used, default=5750) + 10
        for k, config in enumerate(configs):  # a second fleet gets ports of its own
            if not config.port:
                config.port = base + 10 * k
        sim = Simulator(configs, seed=seed)
        await sim.start()
        self.simulators.append(sim)
        return sim

    async def at_starts(
        self, scenario: Scenario, faults: Faults | None = None, seed: int = 1, **config: Any
    ) -> Simulator:
        return await self.start(configs_at_starts(scenario, faults, **config), seed)

    async def open(self, endpoint: Endpoint) -> ByteTransport:
        """A TCP connection string to a simulated vehicle's nominal port, in memory."""
        for sim in self.simulators:
            if endpoint.port in sim.ports():
                return MemoryTransport(sim.memory_port_at(endpoint.port))
        raise LinkError(f"cannot connect to {endpoint}: connection refused (no vehicle there)")

    async def stop(self) -> None:
        for sim in self.simulators:
            await sim.stop()
        self.simulators.clear()

"""`mvo-gcs demo`: the service with embedded storage and mock vehicles, ready to fly.

The vehicles (sitl_mock, ArduCopter flavour) sit at the start cells of a scenario (the
paper's case VI unless told otherwise) and are registered with the service, so an
operator can go from scenario to landed fleet with a handful of HTTP requests.
"""

from __future__ import annotations

import argparse
import asyncio
import json
from pathlib import Path

from gcs.cli.serve import add_arguments as add_serve_arguments
from gcs.cli.serve import serve, settings_from, upgrade_storage
from gcs.mavlink.endpoint import Endpoint
from gcs.mission.geodesy import GridFrame
from gcs.service.settings import Settings
from gcs.service.storage import Database, VehicleRepository
from gcs.service.storage.tables import VehicleRow
from planner.cases import load_case
from planner.model.scenario import Scenario, load_scenario
from sitl_mock import Simulator, VehicleConfig


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_serve_arguments(parser)
    parser.add_argument(
        "--scenario",
        type=Path,
        default=None,
        help="place one vehicle at each UAV's start (default: the paper's case VI)",
    )
    parser.add_argument("--speedup", type=float, default=5.0, help="simulated time factor")
    parser.add_argument(
        "--base-port",
        type=int,
        default=5760,
        help="vehicle i serves TCP base + 10 (i - 1), as ArduPilot SITL (default 5760)",
    )


def run(args: argparse.Namespace) -> int:
    settings = settings_from(args).model_copy(update={"show_token": True})
    upgrade_storage(settings)
    scenario = load_scenario(args.scenario.read_text()) if args.scenario else load_case("case-6")
    simulator = vehicles_at_starts(scenario, args.speedup, args.base_port)
    with simulator.running():
        for line in register(settings, simulator):
            print(line, flush=True)
        print(
            f"mvo-gcs: scenario for these vehicles: {args.scenario or 'planner/cases/case-6.json'}",
            flush=True,
        )
        serve(settings)
    return 0


def vehicles_at_starts(scenario: Scenario, speedup: float, base_port: int) -> Simulator:
    frame = GridFrame.of(scenario)
    configs = []
    for sysid, uav in enumerate(scenario.uavs, start=1):
        lat, lon = frame.to_geodetic(*uav.start)
        home = (float(lat), float(lon), frame.alt0)
        port = base_port + 10 * (sysid - 1)
        configs.append(VehicleConfig(sysid=sysid, port=port, home=home, transport="tcp"))
    return Simulator(configs, speedup=speedup, seed=1)


def register(settings: Settings, simulator: Simulator) -> list[str]:
    """Store each vehicle once (a second demo run finds them registered already)."""
    return asyncio.run(_register(settings, simulator))


async def _register(settings: Settings, simulator: Simulator) -> list[str]:
    settings.data_dir.mkdir(parents=True, exist_ok=True, mode=0o700)  # the service tightens it
    db = Database(settings.resolved_database_url)
    vehicles = VehicleRepository(db)
    lines = []
    try:
        for sysid in simulator.sysids:
            connection = str(Endpoint.parse(simulator.connection_string(sysid)))
            row = await vehicles.by_connection(connection, sysid) or await vehicles.add(
                VehicleRow(name=f"mock vehicle {sysid}", connection=connection, sysid=sysid)
            )
            lines.append(f"mvo-gcs: vehicle {row.id} = {json.dumps(connection)} (sysid {sysid})")
    finally:
        db.close()
    return lines

"""`mvo-gcs sitl` / `python -m sitl_mock`: start N simulated vehicles and run until SIGINT or
SIGTERM.

The defaults are what ArduPilot SITL users know: vehicle i (system id i) serves TCP on
5760 + 10 (i - 1). `--out udp:HOST:PORT` (repeatable) makes every vehicle also send to a
listening ground station, all through one socket per address as MAVProxy's outputs do,
so QGroundControl's or MAVProxy's UDP port 14550 sees them all. `--transport udp` keeps
the older mode: each vehicle waits on its own UDP port (base 14560) for a ground station
to speak first."""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import signal
import sys
from pathlib import Path

from .codec import mavlink
from .connection_help import output_lines, server_lines
from .faults import REJECT_POINTS, Faults
from .flavour import FLAVOURS
from .geo import offset
from .mission_store import DEFAULT_CAPACITY
from .signing import parse_key
from .simulator import Simulator
from .transport import connection_string, parse_output
from .vehicle import DEFAULT_HOME, VehicleConfig

Home = tuple[float, float, float]
PORT_STRIDE = 10
BASE_PORTS = {"tcp": 5760, "udp": 14560}
"""Vehicle 1's port: ArduPilot SITL's TCP 5760; UDP as this command always had it."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The `sitl` options (shared by `mvo-gcs sitl` and `python -m sitl_mock`)."""
    parser.add_argument(
        "--vehicles",
        type=_positive_int,
        default=None,
        help="number of vehicles, system ids 1..N (default: 1, or one per "
        "entry of --homes / UAV of --scenario)",
    )
    parser.add_argument(
        "--transport",
        choices=("tcp", "udp"),
        default="tcp",
        help="each vehicle's own server: tcp (as ArduPilot SITL, default) or "
        "udp (waits for the ground station to speak first)",
    )
    parser.add_argument(
        "--base-port",
        type=int,
        default=None,
        help="vehicle 1's port; vehicle i listens on BASE + STRIDE (i - 1) "
        "(default 5760 for tcp, 14560 for udp; 0: chosen by the OS)",
    )
    parser.add_argument(
        "--port-stride",
        type=_positive_int,
        default=PORT_STRIDE,
        help="ports between neighbouring vehicles (default 10, as SITL's -I)",
    )
    parser.add_argument(
        "--out",
        action="append",
        default=[],
        type=_output,
        metavar="udp:HOST:PORT",
        help="also send to a ground station listening there (repeatable; "
        "all vehicles share it, e.g. udp:127.0.0.1:14550 for QGC)",
    )
    parser.add_argument("--bind", default="127.0.0.1", help="address to listen on")
    parser.add_argument(
        "--autopilot",
        choices=sorted(FLAVOURS),
        default="ardupilot",
        help="which autopilot to behave like",
    )
    parser.add_argument(
        "--speedup", type=_positive_float, default=1.0, help="simulated seconds per wall second"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of every random choice")
    parser.add_argument(
        "--home",
        type=_home,
        default=DEFAULT_HOME,
        metavar="LAT,LON,ALT",
        help="home of vehicle 1; the others are placed --spacing metres apart",
    )
    parser.add_argument(
        "--spacing",
        type=_positive_float,
        default=20.0,
        help="metres between neighbouring homes on a grid (default 20)",
    )
    parser.add_argument(
        "--homes",
        type=Path,
        metavar="FILE",
        help="JSON list of [lat, lon, alt] homes, one per vehicle",
    )
    parser.add_argument(
        "--scenario",
        type=Path,
        metavar="SCENARIO.json",
        help="place vehicle i at the start cell of the scenario's i-th UAV",
    )
    parser.add_argument(
        "--track-log",
        type=Path,
        metavar="FILE",
        help="write every vehicle's track as JSON lines (10 per sim second)",
    )
    parser.add_argument(
        "--stream-by-default",
        action="store_true",
        help="stream telemetry without being asked (ArduPilot flavour)",
    )
    parser.add_argument(
        "--estimate-delay",
        type=float,
        default=None,
        metavar="S",
        help="simulated seconds after boot until arming in GUIDED works "
        "(default: ArduCopter's 41.5, PX4 5)",
    )
    parser.add_argument(
        "--position-delay",
        type=float,
        default=None,
        metavar="S",
        help="simulated seconds after boot until home is set (default 20)",
    )
    parser.add_argument(
        "--signing-key",
        type=parse_key,
        default=None,
        metavar="KEY",
        help="MAVLink 2 signing: 64 hex digits, or a passphrase (SHA-256, as "
        "MAVProxy's `signing setup`); vehicles then ignore unsigned packets",
    )
    parser.add_argument(
        "--mission-capacity",
        type=_positive_int,
        default=DEFAULT_CAPACITY,
        help="most mission items a vehicle accepts",
    )
    faults = parser.add_argument_group("faults (every vehicle; delays in simulated seconds)")
    faults.add_argument(
        "--loss-in",
        type=_fraction,
        default=0.0,
        help="fraction of packets from the ground station lost",
    )
    faults.add_argument(
        "--loss-out",
        type=_fraction,
        default=0.0,
        help="fraction of packets to the ground station lost",
    )
    faults.add_argument("--latency", type=float, default=0.0, metavar="S")
    faults.add_argument("--jitter", type=float, default=0.0, metavar="S")
    faults.add_argument("--duplicate", type=_fraction, default=0.0)
    faults.add_argument("--reorder", type=_fraction, default=0.0)
    faults.add_argument(
        "--reject-missions",
        nargs="?",
        const="last_item",
        default=None,
        choices=REJECT_POINTS,
        help="refuse uploads with MAV_MISSION_ERROR at the COUNT or the last "
        "item (default last_item)",
    )
    faults.add_argument(
        "--fail-arming", action="store_true", help="every arming attempt fails, ready or not"
    )
    faults.add_argument(
        "--refuse-takeoff",
        action="store_true",
        help="NAV_TAKEOFF and MISSION_START fail once armed",
    )
    faults.add_argument(
        "--refuse-command",
        action="append",
        default=[],
        type=_command,
        metavar="CMD",
        help="answer this MAV_CMD (number or name, e.g. MAV_CMD_MISSION_START) FAILED (repeatable)",
    )


def run(args: argparse.Namespace) -> int:
    try:
        configs = vehicle_configs(args)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"sitl: error: {exc}", file=sys.stderr)
        return 2
    sim = Simulator(
        configs,
        speedup=args.speedup,
        seed=args.seed,
        host=args.bind,
        stream_by_default=args.stream_by_default,
        track_log=args.track_log,
    )
    return asyncio.run(_serve(sim))


def vehicle_port(args: argparse.Namespace, sysid: int) -> int:
    """Vehicle `sysid`'s port: BASE + STRIDE (sysid - 1), or 0 (the OS picks) for base 0."""
    base = BASE_PORTS[args.transport] if args.base_port is None else args.base_port
    return base and base + args.port_stride * (sysid - 1)


def vehicle_configs(args: argparse.Namespace) -> list[VehicleConfig]:
    homes = _homes(args)
    faults = Faults(
        loss_in=args.loss_in,
        loss_out=args.loss_out,
        latency_s=args.latency,
        jitter_s=args.jitter,
        duplicate=args.duplicate,
        reorder=args.reorder,
        reject_missions=args.reject_missions is not None,
        reject_at=args.reject_missions or "last_item",
        fail_arming=args.fail_arming,
        refuse_takeoff=args.refuse_takeoff,
        refuse_commands=frozenset(args.refuse_command),
    )
    return [
        VehicleConfig(
            sysid=i,
            port=vehicle_port(args, i),
            home=home,
            autopilot=args.autopilot,
            transport=args.transport,
            faults=faults,
            mission_capacity=args.mission_capacity,
            estimate_delay_s=args.estimate_delay,
            position_delay_s=args.position_delay,
            signing_key=args.signing_key,
            outputs=tuple(args.out),
        )
        for i, home in enumerate(homes, start=1)
    ]


async def _serve(sim: Simulator) -> int:
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for signum in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(signum, stop.set)
    await sim.start()
    try:
        print("\n".join(startup_lines(sim)), flush=True)
        await stop.wait()
    finally:
        await sim.stop()
    return 0


def startup_lines(sim: Simulator) -> list[str]:
    """One `vehicle N: <pymavlink string>` line each, then what to paste into each client."""
    lines = []
    for sysid in sim.sysids:
        config = sim.vehicle(sysid).config
        lines.append(
            f"vehicle {sysid}: {connection_string(config.transport, sim.host, sim.port(sysid))}"
        )
    for sysid in sim.sysids:
        config = sim.vehicle(sysid).config
        lines.append(f"vehicle {sysid} (system id {sysid}), its own {config.transport} server:")
        lines += [f"  {line}" for line in server_lines(config.transport, sim.host, sim.port(sysid))]
    for host, port in sim.output_addresses():
        lines.append(f"every vehicle sends to udp:{host}:{port}; listen there with:")
        lines += [f"  {line}" for line in output_lines(host, port)]
    return lines


def _homes(args: argparse.Namespace) -> list[Home]:
    if args.homes and args.scenario:
        raise ValueError("give --homes or --scenario, not both")
    if args.homes:
        homes = _homes_file(args.homes)
    elif args.scenario:
        homes = scenario_homes(args.scenario)
    else:
        return grid_homes(args.home, args.vehicles or 1, args.spacing)
    count = args.vehicles or len(homes)
    if count > len(homes):
        raise ValueError(f"{count} vehicles but only {len(homes)} homes")
    return homes[:count]


def grid_homes(first: Home, count: int, spacing: float) -> list[Home]:
    """Homes on a square grid, `spacing` metres apart, the first at `first`."""
    columns = math.ceil(math.sqrt(count))
    lat, lon, alt = first
    return [
        (*offset(lat, lon, alt, spacing * (i % columns), spacing * (i // columns)), alt)
        for i in range(count)
    ]


def scenario_homes(path: Path) -> list[Home]:
    """The start cells of a scenario's UAVs: cell (x, y) is x cells east, y cells north."""
    scenario = json.loads(path.read_text())
    cell = float(scenario["grid"]["cell_size_m"])
    origin = scenario["origin"]
    lat, lon, alt = float(origin["lat"]), float(origin["lon"]), float(origin["alt_m"])
    homes = []
    for uav in scenario["uavs"]:
        x, y = uav["start"]
        homes.append((*offset(lat, lon, alt, x * cell, y * cell), alt))
    return homes


def _homes_file(path: Path) -> list[Home]:
    entries = json.loads(path.read_text())
    if not isinstance(entries, list) or not all(
        isinstance(e, list) and len(e) == 3 for e in entries
    ):
        raise ValueError(f"{path}: expected a JSON list of [lat, lon, alt]")
    return [(float(lat), float(lon), float(alt)) for lat, lon, alt in entries]


def _home(text: str) -> Home:
    try:
        lat, lon, alt = (float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LAT,LON,ALT, got {text!r}") from None
    return lat, lon, alt


def _output(text: str) -> str:
    try:
        parse_output(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _command(text: str) -> int:
    """A MAV_CMD by number or pymavlink name."""
    if text.isdigit():
        return int(text)
    name = text if text.startswith("MAV_CMD_") else f"MAV_CMD_{text}"
    value = getattr(mavlink, name.upper(), None)
    if not isinstance(value, int):
        raise argparse.ArgumentTypeError(f"unknown command {text!r}")
    return value


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {value}")
    return value


def _fraction(text: str) -> float:
    value = float(text)
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"must be a fraction in [0, 1], got {value}")
    return value

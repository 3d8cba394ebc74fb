"""Benchmark of the simulated vehicles (sitl_mock).

1. 50 vehicles in one process at 10x speed-up, every telemetry stream requested at its
   default rate: CPU used by the simulator process and telemetry messages per second
   received by a listening client.
2. A 100-item mission upload from pymavlink over loopback UDP: median milliseconds over
   20 uploads.

The simulator runs as `python -m sitl_mock` in a subprocess (pinned to core 0 with
`taskset` when available); the client runs here. Results go to bench/results/sitl.md.

    python bench/sitl_bench.py [--vehicles 50] [--speedup 10] [--seconds 20] [--uploads 20]
"""

from __future__ import annotations

import argparse
import os
import platform
import select
import shutil
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil

mavutil.set_dialect("ardupilotmega")
mavlink = mavutil.mavlink

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "sitl.md"
STREAMS = [
    mavlink.MAVLINK_MSG_ID_SYS_STATUS,
    mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,
    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
    mavlink.MAVLINK_MSG_ID_ATTITUDE,
    mavlink.MAVLINK_MSG_ID_VFR_HUD,
    mavlink.MAVLINK_MSG_ID_HOME_POSITION,
    mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
    mavlink.MAVLINK_MSG_ID_MISSION_CURRENT,
]
EXPECTED_HZ = 1 + 1 + 1 + 5 + 10 + 4 + 0.5 + 1 + 1
"""Per vehicle, simulated seconds: heartbeat plus the default rates in sitl_mock.telemetry."""
CLK_TCK = os.sysconf("SC_CLK_TCK")


def start_simulator(vehicles: int, speedup: float, pin: bool) -> tuple[subprocess.Popen, list]:
    command = [
        sys.executable,
        "-m",
        "sitl_mock",
        "--vehicles",
        str(vehicles),
        "--base-port",
        "0",
        "--speedup",
        str(speedup),
        "--estimate-delay",
        "0",
    ]
    if pin and shutil.which("taskset"):
        command = ["taskset", "-c", "0", *command]
    proc = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, text=True)
    ports = []
    for _ in range(vehicles):
        line = proc.stdout.readline()
        ports.append(int(line.rsplit(":", 1)[1]))
    return proc, ports


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def telemetry_bench(vehicles: int, speedup: float, seconds: float, pin: bool) -> dict:
    proc, ports = start_simulator(vehicles, speedup, pin)
    try:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
        sock.bind(("127.0.0.1", 0))
        mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)

        def say_hello(request_streams: bool) -> None:
            for sysid, port in enumerate(ports, start=1):
                packets = [mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3)]
                if request_streams:  # interval 0 = the message's default rate
                    packets += [
                        mavlink.MAVLink_command_long_message(
                            sysid,
                            1,
                            mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                            0,
                            msg_id,
                            0,
                            0,
                            0,
                            0,
                            0,
                            0,
                        )
                        for msg_id in STREAMS
                    ]
                for packet in packets:
                    sock.sendto(packet.pack(mav), ("127.0.0.1", port))

        say_hello(request_streams=True)
        time.sleep(1.0)  # let the streams start, then forget what queued meanwhile
        _drain(sock)
        cpu_start, wall_start = cpu_seconds(proc.pid), time.monotonic()
        received, next_hello = 0, wall_start + 2.0
        while (now := time.monotonic()) < wall_start + seconds:
            if now >= next_hello:
                say_hello(request_streams=False)
                next_hello = now + 2.0
            ready, _, _ = select.select([sock], [], [], 0.1)
            while ready:
                try:
                    sock.recv(2048, socket.MSG_DONTWAIT)
                    received += 1
                except BlockingIOError:
                    break
        wall = time.monotonic() - wall_start
        cpu = cpu_seconds(proc.pid) - cpu_start
        sock.close()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    return {
        "cpu_fraction": cpu / wall,
        "messages_per_s": received / wall,
        "expected_per_s": EXPECTED_HZ * speedup * vehicles,
        "wall_s": wall,
    }


def _drain(sock: socket.socket) -> None:
    while True:
        try:
            sock.recv(2048, socket.MSG_DONTWAIT)
        except BlockingIOError:
            return


def upload_bench(uploads: int, items: int, pin: bool) -> list[float]:
    proc, ports = start_simulator(1, 1.0, pin)
    try:
        link = mavutil.mavlink_connection(f"udpout:127.0.0.1:{ports[0]}", source_system=255)
        link.mav.heartbeat_send(6, 8, 0, 0, 0)
        link.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
        times = []
        for _ in range(uploads):
            start = time.perf_counter()
            result = _upload(link, items)
            times.append((time.perf_counter() - start) * 1000)
            if result != 0:
                raise RuntimeError(f"upload failed with MISSION_ACK {result}")
        link.close()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    return times


def _upload(link, count: int) -> int:
    link.mav.mission_count_send(1, 1, count, 0)
    while True:
        msg = link.recv_match(
            type=["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"], blocking=True, timeout=5
        )
        if msg is None:
            return -1
        if msg.get_type() == "MISSION_ACK":
            return msg.type
        link.mav.mission_item_int_send(
            1, 1, msg.seq, 6, 16, 0, 1, 0, 0, 0, 0, 473977000 + msg.seq * 100, 85456000, 20.0, 0
        )


def machine() -> list[str]:
    cpu = next(
        (
            line.split(":", 1)[1].strip()
            for line in Path("/proc/cpuinfo").read_text().splitlines()
            if line.startswith("model name")
        ),
        platform.processor(),
    )
    load = os.getloadavg()
    return [
        f"- platform: {platform.platform()}",
        f"- CPU: {cpu}",
        f"- cores: {os.cpu_count()} logical",
        f"- Python: {platform.python_version()}",
        f"- load average before the run: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}",
    ]


def report(
    args: argparse.Namespace, telemetry: dict, uploads: list[float], machine_lines: list[str]
) -> str:
    median = statistics.median(uploads)
    pinned = bool(args.pin and shutil.which("taskset"))
    cpu_ok = telemetry["cpu_fraction"] < 1.0
    rate_share = telemetry["messages_per_s"] / telemetry["expected_per_s"]
    return "\n".join(
        [
            "# sitl_mock benchmark",
            "",
            f"{args.vehicles} simulated vehicles in one process at {args.speedup:g}x speed-up, "
            "every stream requested at its default rate with SET_MESSAGE_INTERVAL(id, 0), for "
            f"{telemetry['wall_s']:.0f} s of wall time; a listening client on loopback UDP counts "
            "what arrives. Then a 100-item mission upload from pymavlink (answering each "
            f"MISSION_REQUEST with MISSION_ITEM_INT), {len(uploads)} times, against one vehicle.",
            "",
            "## Machine",
            "",
            *machine_lines,
            f"- simulator pinned to core 0: {'yes' if pinned else 'no'}",
            "",
            "## Command",
            "",
            "```",
            f"python bench/sitl_bench.py --vehicles {args.vehicles} --speedup {args.speedup:g} "
            f"--seconds {args.seconds:g} --uploads {args.uploads}",
            "```",
            "",
            "## Results",
            "",
            "| measure | value | target | verdict |",
            "|---|---:|---:|---|",
            f"| simulator CPU (fraction of one core) | {telemetry['cpu_fraction']:.2f} | < 1.0 | "
            f"{'met' if cpu_ok else 'missed'} |",
            f"| telemetry received (messages/s) | {telemetry['messages_per_s']:.0f} | "
            f"{telemetry['expected_per_s']:.0f} configured | {rate_share:.1%} of configured |",
            f"| 100-item upload, median ms | {median:.1f} | ≤ 100 | "
            f"{'met' if median <= 100 else 'missed'} |",
            f"| 100-item upload, min / max ms | {min(uploads):.1f} / {max(uploads):.1f} | | |",
            "",
            "Telemetry rates run on simulated time, so at 10x each vehicle sends ten times its "
            f"per-second rates ({EXPECTED_HZ:g} messages per simulated second: heartbeat 1 Hz, "
            "SYS_STATUS 1, GPS_RAW_INT 1, GLOBAL_POSITION_INT 5, ATTITUDE 10, VFR_HUD 4, "
            "HOME_POSITION 0.5, EXTENDED_SYS_STATE 1, MISSION_CURRENT 1).",
            "",
            "The vehicles stand disarmed on the ground during the telemetry run: telemetry, not "
            "flight, dominates the cost (the fleet's physics is one numpy step for all vehicles).",
            "",
            "The machine has two cores shared with other work running at the same time; numbers "
            "taken under load (see the load average above) can be pessimistic.",
            "",
        ]
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--vehicles", type=int, default=50)
    parser.add_argument("--speedup", type=float, default=10.0)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--uploads", type=int, default=20)
    parser.add_argument("--no-pin", dest="pin", action="store_false")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args()
    machine_lines = machine()
    telemetry = telemetry_bench(args.vehicles, args.speedup, args.seconds, args.pin)
    print(f"telemetry: {telemetry}")
    uploads = upload_bench(args.uploads, 100, args.pin)
    print(f"upload ms: median {statistics.median(uploads):.1f}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(report(args, telemetry, uploads, machine_lines))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""`mvo-gcs fly` end to end: plan, upload, fly and report the separation flown.

The flight runs on the virtual clock: the command's own event loop (`asyncio.run`) is a
virtual-time loop on which the vehicles run in memory, and its connections open their
in-memory ports (the command's connection strings are the vehicles' nominal TCP ones).
The links' sockets are tested in test_link.py and the conformance tests."""

from __future__ import annotations

import asyncio
import functools
import re
from collections.abc import Coroutine
from dataclasses import replace
from typing import Any

import pytest

from gcs.cli.main import main
from gcs.mavlink import client
from gcs.mission.flight_plan import FlightPlan
from gcs.mission.flight_timing import FlightStuck
from planner.cases import load_case
from sitl_mock.snapshot import VehicleState
from sitl_mock.virtual_time import run_virtual
from tests.inprocess.vehicles import SimulatedVehicles

from .flights import vehicles_at_starts


def fly_case_1(monkeypatch: pytest.MonkeyPatch, *options: str) -> tuple[int, list[VehicleState]]:
    """`mvo-gcs fly case-1` on mock vehicles on the virtual clock: its exit code, and each
    vehicle's state as the command left it."""
    configs = [  # on SITL's nominal ports, 5760 + 10 (k - 1)
        replace(c, transport="memory", port=5750 + 10 * c.sysid)
        for c in vehicles_at_starts(load_case("case-1"))
    ]
    vehicles = SimulatedVehicles()
    states: list[VehicleState] = []

    async def with_vehicles(command: Coroutine[Any, Any, int]) -> int:
        sim = await vehicles.start(configs)
        try:
            return await command
        finally:
            states.extend(sim.state(sysid) for sysid in sim.sysids)
            await vehicles.stop()

    urls = ",".join(f"tcp:127.0.0.1:{c.port}" for c in configs)
    # The command takes no loop or transport opener: its asyncio.run and client.connect
    # are the seams (a test on the old sockets would fail to connect, not pass unseen).
    monkeypatch.setattr(asyncio, "run", lambda command: run_virtual(with_vehicles(command)))
    monkeypatch.setattr(client, "connect", functools.partial(client.connect, opener=vehicles.open))
    code = main(["fly", "case-1", "--vehicles", urls, "--altitude", "10", *options])
    assert states, "the command's flight did not run on the virtual clock"
    return code, states


def test_fly_plans_flies_and_reports_the_separation(
    capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    code, states = fly_case_1(monkeypatch)
    out = capsys.readouterr().out
    assert code == 0, out
    assert "2 missions started" in out
    assert "separation flown:" in out and "required 2R: 6.00 m" in out
    assert all(s.mission_total > 0 and not s.armed for s in states)  # flown, landed


def test_a_dry_run_prints_the_timing_and_uploads_and_arms_nothing(
    capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    code, states = fly_case_1(monkeypatch, "--dry-run", "--max-speed", "10")
    out = capsys.readouterr().out
    assert code == 0, out
    assert "timed at up to 10 m/s" in out and "s to the last goal" in out
    assert "uav1: over its goal at " in out and "uav2: over its goal at " in out
    assert "dry run: nothing was uploaded or armed" in out
    assert "missions started" not in out
    assert all(s.mission_total == 0 and not s.armed for s in states)


def test_with_candidates_every_seed_is_timed_and_the_soonest_flown(
    capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    code, states = fly_case_1(monkeypatch, "--dry-run", "--candidates", "3", "--seed", "4")
    out = capsys.readouterr().out
    assert code == 0, out
    assert "(3 candidates)" in out and "candidates timed at 5 m/s:" in out
    lines = [line.strip() for line in out.splitlines() if line.startswith("  seed ")]
    assert [line.split(":")[0] for line in lines] == [
        "seed 4, clearance 1.3 m", "seed 5, clearance 1.8 m", "seed 6, clearance 2.3 m",
    ]  # fmt: skip
    timed = [float(m) for m in re.findall(r"^  seed \d+, clearance .* m: ([\d.]+) s", out, re.M)]
    assert timed, out  # seed 4 at least is timed; the others may share its paths
    assert sum("(flown)" in line for line in lines) == 1
    last_goal = re.search(r"timed at up to 5 m/s, .*: ([\d.]+) s to the last goal", out)
    assert last_goal is not None and abs(float(last_goal[1]) - min(timed)) <= 0.05, out
    assert all(s.mission_total == 0 and not s.armed for s in states)


def test_a_passing_order_the_vehicles_cannot_keep_is_refused_before_anything_arms(
    capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Fuzzed flight 13783's plan, whose timing found its order stuck, was a 500 from the
    service; from the terminal it was a traceback. Now it is exit 2, as a speed is."""

    def stuck(flight: FlightPlan) -> float:
        raise FlightStuck("['uav1', 'uav2'] stopped moving at 80 s of the simulated flight")

    monkeypatch.setattr(FlightPlan, "duration_s", property(stuck))
    code, states = fly_case_1(monkeypatch)
    captured = capsys.readouterr()
    assert code == 2, captured.out
    assert "cannot keep the plan's passing order" in captured.err
    assert "nothing was armed" in captured.err
    assert all(s.mission_total == 0 and not s.armed for s in states)


def test_fly_refuses_a_vehicle_count_that_does_not_match(capsys) -> None:
    with pytest.raises(SystemExit) as caught:
        main(["fly", "case-1", "--vehicles", "udpout:127.0.0.1:9"])
    assert caught.value.code == 2
    assert "2 UAVs in case-1 but 1 vehicles given" in capsys.readouterr().err


def test_fly_exits_1_when_a_vehicle_cannot_be_reached(capsys) -> None:
    code = main(
        [
            "fly",
            "case-1",
            "--vehicles",
            "udpout:127.0.0.1:9,udpout:127.0.0.1:11",
            "--connect-timeout",
            "0.3",
            "--iterations",
            "50",
        ]
    )
    assert code == 1
    assert "cannot reach every vehicle" in capsys.readouterr().err

"""`mvo-gcs fly` end to end: plan, upload, fly and report the separation flown."""

from __future__ import annotations

import pytest

from gcs.cli.main import main
from planner.cases import load_case
from sitl_mock import Simulator

from .flights import vehicles_at_starts


def test_fly_plans_flies_and_reports_the_separation(capsys) -> None:
    sim = Simulator(vehicles_at_starts(load_case("case-1")), speedup=40.0)
    with sim.running():
        urls = ",".join(sim.connection_string(k) for k in (1, 2))
        code = main(["fly", "case-1", "--vehicles", urls, "--altitude", "10"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "2 missions started" in out
    assert "separation flown:" in out and "required 2R: 6.00 m" in out


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

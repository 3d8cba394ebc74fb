"""Command-line parsing and vehicle placement (grid, --homes, --scenario)."""

from __future__ import annotations

import argparse
import hashlib
import json

import pymap3d
import pytest

from sitl_mock.cli import add_arguments, run, vehicle_configs
from sitl_mock.codec import mavlink


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(list(argv))


def enu(home, origin):
    east, north, _ = pymap3d.geodetic2enu(home[0], home[1], origin[2], *origin)
    return east, north


def test_defaults_are_ardupilot_sitls_one_tcp_vehicle_on_5760():
    (config,) = vehicle_configs(parse())
    assert (config.sysid, config.port, config.autopilot, config.transport) == (
        1,
        5760,
        "ardupilot",
        "tcp",
    )
    assert config.faults.link_is_clean and not config.faults.reject_missions
    assert config.outputs == () and config.signing_key is None
    assert config.estimate_delay_s is None and config.timeline().estimate_s == 41.5


def test_udp_listening_vehicles_keep_their_ports_from_14560():
    configs = vehicle_configs(parse("--vehicles", "3", "--transport", "udp"))
    assert [(c.transport, c.port) for c in configs] == [
        ("udp", 14560),
        ("udp", 14570),
        ("udp", 14580),
    ]


def test_vehicles_get_ports_ten_apart_and_homes_twenty_metres_apart():
    configs = vehicle_configs(
        parse("--vehicles", "4", "--home=-35.36,149.16,584", "--autopilot", "px4")
    )
    assert [c.port for c in configs] == [5760, 5770, 5780, 5790]
    assert [c.sysid for c in configs] == [1, 2, 3, 4]
    origin = configs[0].home
    offsets = [enu(c.home, origin) for c in configs]
    assert offsets == [pytest.approx(p, abs=1e-3) for p in [(0, 0), (20, 0), (0, 20), (20, 20)]]
    assert all(c.home[2] == 584 and c.autopilot == "px4" for c in configs)


def test_homes_file_places_each_vehicle_exactly(tmp_path):
    homes = [[47.1, 8.1, 400.0], [47.2, 8.2, 410.0], [47.3, 8.3, 420.0]]
    path = tmp_path / "homes.json"
    path.write_text(json.dumps(homes))
    assert [list(c.home) for c in vehicle_configs(parse("--homes", str(path)))] == homes
    assert len(vehicle_configs(parse("--homes", str(path), "--vehicles", "2"))) == 2


def test_scenario_places_vehicles_at_their_start_cells(tmp_path):
    scenario = {
        "grid": {"width": 6, "height": 6, "cell_size_m": 10.0},
        "origin": {"lat": -35.363262, "lon": 149.165237, "alt_m": 584.0},
        "uavs": [
            {"id": "a", "start": [0, 2], "goal": [4, 2]},
            {"id": "b", "start": [4, 1], "goal": [0, 2]},
        ],
    }
    path = tmp_path / "scenario.json"
    path.write_text(json.dumps(scenario))
    configs = vehicle_configs(parse("--scenario", str(path)))
    origin = (-35.363262, 149.165237, 584.0)
    assert enu(configs[0].home, origin) == pytest.approx((0.0, 20.0), abs=1e-3)
    assert enu(configs[1].home, origin) == pytest.approx((40.0, 10.0), abs=1e-3)
    assert all(c.home[2] == 584.0 for c in configs)


def test_fault_options_reach_every_vehicle():
    configs = vehicle_configs(
        parse(
            "--vehicles",
            "2",
            "--loss-in",
            "0.1",
            "--loss-out",
            "0.2",
            "--latency",
            "0.05",
            "--jitter",
            "0.01",
            "--duplicate",
            "0.3",
            "--reorder",
            "0.4",
            "--reject-missions",
            "count",
        )
    )
    for config in configs:
        f = config.faults
        assert (f.loss_in, f.loss_out, f.latency_s, f.jitter_s, f.duplicate, f.reorder) == (
            0.1,
            0.2,
            0.05,
            0.01,
            0.3,
            0.4,
        )
        assert f.reject_missions and f.reject_at == "count"
    assert vehicle_configs(parse("--reject-missions"))[0].faults.reject_at == "last_item"


def test_outputs_keys_readiness_and_refusals_reach_every_vehicle():
    configs = vehicle_configs(
        parse(
            "--vehicles",
            "2",
            "--out",
            "udp:127.0.0.1:14550",
            "--out",
            "udp:127.0.0.1:14551",
            "--signing-key",
            "ab" * 32,
            "--estimate-delay",
            "3",
            "--position-delay",
            "2",
            "--fail-arming",
            "--refuse-takeoff",
            "--refuse-command",
            "MAV_CMD_MISSION_START",
            "--refuse-command",
            "176",
            "--port-stride",
            "1",
            "--base-port",
            "6000",
        )
    )
    assert [c.port for c in configs] == [6000, 6001]
    for config in configs:
        assert config.outputs == ("udp:127.0.0.1:14550", "udp:127.0.0.1:14551")
        assert config.signing_key == bytes.fromhex("ab" * 32)
        timeline = config.timeline()
        assert (timeline.origin_s, timeline.estimate_s) == (2.0, 3.0)
        faults = config.faults
        assert faults.fail_arming and faults.refuse_takeoff
        assert faults.refuse_commands == {
            mavlink.MAV_CMD_MISSION_START,
            mavlink.MAV_CMD_DO_SET_MODE,
        }


def test_a_passphrase_is_hashed_into_a_key_as_mavproxy_does():
    (config,) = vehicle_configs(parse("--signing-key", "correct horse"))
    assert config.signing_key == hashlib.sha256(b"correct horse").digest()


@pytest.mark.parametrize(
    "argv",
    [
        ["--vehicles", "0"],
        ["--loss-in", "2"],
        ["--home", "1,2"],
        ["--transport", "serial"],
        ["--speedup", "0"],
        ["--out", "tcp:127.0.0.1:14550"],
        ["--out", "udp:host:0"],
        ["--refuse-command", "NO_SUCH_COMMAND"],
    ],
)
def test_bad_options_are_refused(argv, capsys):
    with pytest.raises(SystemExit):
        parse(*argv)


def test_more_vehicles_than_homes_is_a_user_error(tmp_path, capsys):
    path = tmp_path / "homes.json"
    path.write_text("[[1, 2, 3]]")
    assert run(parse("--homes", str(path), "--vehicles", "2")) == 2
    assert "only 1 homes" in capsys.readouterr().err

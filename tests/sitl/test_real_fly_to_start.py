"""Real ArduCopter SITL standing 5-6 m off its start cells' centres (where a geographic
scenario, a start "at vehicle X" included, puts the planned starts): `mvo-gcs fly` takes
each off where it stands, sends it to its start (SET_POSITION_TARGET_GLOBAL_INT in
GUIDED), starts the fleet together once all hold there, and flies the plan. Measured by
the independent observer: where each vehicle was at the common start, the separation
flown (at least 2R) and the landings at the goals.

Run with `ARDUPILOT_SITL=/path/to/arducopter` (skipped otherwise)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gcs.mission.geodesy import GridFrame
from tests.off_centre import OFF_CENTRE_M, homes_off_centre, planned
from tests.sitl.ardupilot_sitl import instances
from tests.sitl.flown import ARRIVAL_M, LAND_DRIFT_M, flown, speedup, two_r
from tests.sitl.observer import Mark, metres_apart, observing

pytestmark = [pytest.mark.sitl, pytest.mark.slow, pytest.mark.timeout(1800)]
AT_START_M = 1.0
"""Where the vehicle was at the common start, from its start: the ground station waits
for 0.5 m and holding; the observer's last sample before the mission went on may be a
little after the start."""


def test_real_arducopter_off_its_cell_centre_flies_to_its_start_first(tmp_path: Path) -> None:
    scenario, _ = planned()
    source = tmp_path / "scenario.json"
    source.write_text(scenario.model_dump_json())
    homes = homes_off_centre(scenario, OFF_CENTRE_M)
    with (
        instances(homes, tmp_path, speedup(scenario)) as sitl,
        observing([i.port for i in sitl]) as observer,
    ):
        command = [sys.executable, "-m", "gcs.cli", "fly", str(source)]
        command += ["--vehicles", ",".join(i.connection for i in sitl), "--connect-timeout", "60"]
        command += ["--time-budget", "0", "--seed", "1"]
        fly = subprocess.run(command, capture_output=True, text=True, timeout=1800)
        result = flown(observer, scenario)
        frame = GridFrame.of(scenario)
        at_start = {}
        for k, uav in enumerate(scenario.uavs):
            start = result.started_s[uav.id]
            _, lats, lons, _, boot_s = observer.tracks[k].arrays()
            lat, lon = (float(v) for v in frame.to_geodetic(*uav.start))
            home = np.array([homes[k][0]]), np.array([homes[k][1]])
            stood = metres_apart(*home, Mark(0.0, lat, lon, 0.0))[0]
            before = boot_s <= (start if start is not None else -1.0)
            if not before.any():
                at_start[uav.id] = (float(stood), float("inf"))
                continue
            then = metres_apart(lats[before][-1:], lons[before][-1:], Mark(0.0, lat, lon, 0.0))
            at_start[uav.id] = (float(stood), float(then[0]))
    report = fly.stdout[-3000:] + fly.stderr[-3000:]
    print(report)
    print(
        f"off-centre on real ArduCopter: (stood, at the common start) m from the starts "
        f"{ {u: (round(a, 2), round(b, 2)) for u, (a, b) in at_start.items()} }; "
        f"{result.describe()}, 2R {two_r(scenario):.2f} m; landings "
        f"{ {u: round(d, 2) for u, d in result.landed_m.items()} }"
    )
    assert fly.returncode == 0, report
    assert all(5.0 <= stood <= 6.0 for stood, _ in at_start.values()), at_start
    assert all(then <= AT_START_M for _, then in at_start.values()), at_start
    assert result.separation_m is not None and result.separation_m >= two_r(scenario), (
        result.describe()
    )
    assert all(result.down.values()), result.down
    assert max(result.landed_m.values()) <= ARRIVAL_M + LAND_DRIFT_M, result.landed_m
    assert np.isfinite(list(result.landed_m.values())).all()

"""From QGroundControl `.plan` files with a fence to a flight that landed, through the
product's own commands and a real service, with the clearance from the no-fly zones
measured on the vehicles' flown tracks.

1. Two `.plan` files as QGroundControl saves them (tests/geographic.py `qgc_plan`): a
   300 x 200 m inclusion fence, a barn (exclusion polygon), a mast (exclusion circle of
   15 m) and a rally point; each file one UAV (its home the start, its last waypoint the
   goal); the two cross the field past the barn.
2. `mvo-gcs import alpha.plan bravo.plan --cell-size 10 -o yard.geojson`.
3. A real `mvo-gcs serve` (tests/service_process.py) and the mock vehicles in their own
   process (`mvo-gcs sitl --scenario` at the derived starts, `--track-log`); the GeoJSON
   posted as `application/geo+json`, planned, the vehicles bound, uploaded (mission,
   fence, rally points, each read back) and started; the flight waited for to its end.
4. Measured from the simulator's track (10 samples per simulated second, vehicles more
   than 1 m up): each vehicle's least distance from the barn and the mast (shapely, in
   metres around each zone), the closest pair, where each came down; and what the `.plan`
   the service hands out for the plan carries (its geoFence and rallyPoints).

    PYTHONPATH=. .venv/bin/python bench/plan_file_flight.py [--out FILE]
"""

from __future__ import annotations

import argparse
import itertools
import json
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import shapely

from planner.experiments.machine import describe_machine
from tests.geographic import qgc_plan, shape_in_metres, to_metres
from tests.service_process import ServiceProcess, free_port
from tests.sitl.ardupilot_sitl import stop_process

SPEEDUP = 5.0
GEOJSON = {"Content-Type": "application/geo+json"}
PLANS = {"alpha": qgc_plan((25, 25), (275, 175)), "bravo": qgc_plan((275, 25), (25, 175))}


def run(command: list[str]) -> str:
    done = subprocess.run(command, capture_output=True, text=True, check=True)
    return done.stderr.strip()


def wait_for(client: httpx.Client, path: str, done: Any, bound_s: float) -> Any:
    deadline = time.monotonic() + bound_s
    while time.monotonic() < deadline:
        answer = client.get(path)
        if answer.status_code == 200 and done(answer.json()):
            return answer.json()
        time.sleep(0.5)
    raise TimeoutError(f"{path} did not get there in {bound_s:.0f} s")


def fly(work: Path, yard: dict[str, Any]) -> dict[str, Any]:
    service = ServiceProcess(work / "service")
    service.start()
    sim: subprocess.Popen[str] | None = None
    try:
        with service.client() as client:
            created = client.post("/scenarios", content=json.dumps(yard), headers=GEOJSON)
            created.raise_for_status()
            scenario = created.json()
            (work / "grid.json").write_text(json.dumps(scenario["scenario"]))
            port = free_port()
            sim = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "gcs.cli",
                    "sitl",
                    "--scenario",
                    str(work / "grid.json"),
                    "--base-port",
                    str(port),
                    "--speedup",
                    str(SPEEDUP),
                    "--track-log",
                    str(work / "track.jsonl"),
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.STDOUT,
                text=True,
            )
            plan = client.post(f"/scenarios/{scenario['id']}/plans", json={"wait_s": 60})
            plan.raise_for_status()
            plan_id = plan.json()["id"]
            uavs = [u["id"] for u in scenario["scenario"]["uavs"]]
            bindings = {}
            for k, uav in enumerate(uavs):
                vehicle = client.post(
                    "/vehicles", json={"connection": f"tcp:127.0.0.1:{port + 10 * k}"}
                )
                vehicle.raise_for_status()
                bindings[uav] = vehicle.json()["id"]
            flight = client.post("/flights", json={"plan_id": plan_id, "bindings": bindings})
            flight.raise_for_status()
            fid = flight.json()["id"]
            deadline = time.monotonic() + 120
            while (upload := client.post(f"/flights/{fid}/upload")).status_code == 409:
                if time.monotonic() > deadline:
                    raise TimeoutError(upload.text)
                time.sleep(1)
            upload.raise_for_status()
            client.post(f"/flights/{fid}/start").raise_for_status()
            ended = wait_for(
                client, f"/flights/{fid}", lambda f: f["state"] not in ("starting", "flying"), 900
            )
            events = client.get(f"/flights/{fid}/events", params={"limit": 1000}).json()
            handed_out = client.get(f"/plans/{plan_id}/missions/alpha.plan").json()
            return {
                "scenario": scenario,
                "plan": plan.json(),
                "upload": upload.json(),
                "state": ended["state"],
                "events": events,
                "handed_out": handed_out,
                "bindings": bindings,
            }
    finally:
        if sim is not None:
            stop_process(sim)
        service.stop()


def measure(work: Path, yard: dict[str, Any], flown: dict[str, Any]) -> dict[str, Any]:
    rows = [json.loads(line) for line in (work / "track.jsonl").read_text().splitlines()]
    zones = [f for f in yard["features"] if f["properties"]["role"] == "no-fly"]
    goals = {
        f["properties"]["uav"]: f["geometry"]["coordinates"]
        for f in yard["features"]
        if f["properties"]["role"] == "goal"
    }
    uavs = [u["id"] for u in flown["scenario"]["scenario"]["uavs"]]
    radius_m = max(u["radius"] for u in flown["scenario"]["scenario"]["uavs"]) * 10.0
    lon0, lat0 = goals[uavs[0]]
    result: dict[str, Any] = {"radius_m": radius_m, "vehicles": {}}
    tracks = {}
    for sysid, uav in enumerate(uavs, start=1):
        mine = [r for r in rows if r["sysid"] == sysid]
        up = [r for r in mine if r["alt"] > 1.0]
        lat, lon = np.array([r["lat"] for r in up]), np.array([r["lon"] for r in up])
        tracks[uav] = {
            round(r["t"], 1): to_metres(np.array([r["lat"]]), np.array([r["lon"]]), lat0, lon0)[0]
            for r in up
        }
        clearance = {}
        points = shapely.points(to_metres(lat, lon, lat0, lon0))
        for k, zone in enumerate(zones):
            shape = zone_shape(zone, lat0, lon0)
            clearance[f"zone {k}"] = float(shapely.distance(points, shape).min())
        last = mine[-1]
        glon, glat = goals[uav]
        down = to_metres(np.array([last["lat"]]), np.array([last["lon"]]), glat, glon)[0]
        result["vehicles"][uav] = {
            "samples_airborne": len(up),
            "clearance_m": clearance,
            "landed_from_goal_m": float(np.hypot(*down)),
            "landed_alt_m": last["alt"],
        }
    pairs = []
    for a, b in itertools.combinations(uavs, 2):
        common = sorted(set(tracks[a]) & set(tracks[b]))
        if common:
            gaps = [float(np.hypot(*(tracks[a][t] - tracks[b][t]))) for t in common]
            pairs.append((min(gaps), a, b))
    result["closest_pair_m"] = min(pairs) if pairs else None
    return result


def zone_shape(zone: dict[str, Any], lat0: float, lon0: float) -> shapely.Geometry:
    if zone["geometry"]["type"] == "Point":  # a circle: its centre, buffered by its radius
        lon, lat = zone["geometry"]["coordinates"][:2]
        centre = to_metres(np.array([lat]), np.array([lon]), lat0, lon0)[0]
        return shapely.Point(*centre).buffer(zone["properties"]["radius_m"], quad_segs=256)
    return shape_in_metres(zone["geometry"], lat0, lon0)


def report(yard: dict[str, Any], flown: dict[str, Any], measured: dict[str, Any], log: str) -> str:
    fence = flown["handed_out"]["geoFence"]
    kinds = [e["kind"] for e in flown["events"]]
    lines = [
        "# From QGroundControl .plan files with a fence to a flight that landed",
        "",
        f"- Run {datetime.now(UTC):%Y-%m-%d %H:%M} UTC; {describe_machine()}",
        "- Command: `PYTHONPATH=. .venv/bin/python bench/plan_file_flight.py`",
        f"- `mvo-gcs import alpha.plan bravo.plan --cell-size 10`: {log}",
        f"- Grid {flown['scenario']['scenario']['grid']}, "
        f"{len(flown['scenario']['scenario']['obstacles'])} blocked cells; plan feasible: "
        f"{flown['plan']['plan']['feasible']}; mock vehicles (`mvo-gcs sitl`) at speed-up "
        f"{SPEEDUP:g}, flight speed the service's default.",
        "- Upload (mission, fence, rally points, each read back): "
        + ", ".join(
            f"{v['uav_id']} {'ok' if v['ok'] else v['detail']}" for v in flown["upload"]["vehicles"]
        ),
        f"- Flight ended `{flown['state']}`; events: {', '.join(sorted(set(kinds)))}",
        f"- The service's alpha.plan carries {len(fence['polygons'])} fence polygons "
        f"(inclusion: {[p['inclusion'] for p in fence['polygons']]}), "
        f"{len(fence['circles'])} circle(s) and "
        f"{len(flown['handed_out']['rallyPoints']['points'])} rally point(s).",
        "",
        f"R = {measured['radius_m']:.1f} m; margin 1 m; every flown sample with the vehicle more "
        "than 1 m up, measured in metres around each zone (shapely), never on the grid.",
        "",
        "| UAV | samples in the air | clearance from the barn, a polygon (m) "
        "| from the mast, a 15 m circle (m) | landed from its goal (m) |",
        "|---|---:|---:|---:|---:|",
    ]
    for uav, v in measured["vehicles"].items():
        c = list(v["clearance_m"].values())
        lines.append(
            f"| {uav} | {v['samples_airborne']} | {c[0]:.2f} | {c[1]:.2f} | "
            f"{v['landed_from_goal_m']:.2f} |"
        )
    closest = measured["closest_pair_m"]
    if closest:
        lines += [
            "",
            f"Closest pair in the air: {closest[1]}-{closest[2]} {closest[0]:.2f} m "
            f"(2R {2 * measured['radius_m']:.1f} m).",
        ]
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("bench/results/plan_file_flight.md"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for name, document in PLANS.items():
            (work / f"{name}.plan").write_text(json.dumps(document))
        log = run(
            [
                sys.executable,
                "-m",
                "gcs.cli",
                "import",
                str(work / "alpha.plan"),
                str(work / "bravo.plan"),
                "--cell-size",
                "10",
                "-o",
                str(work / "yard.geojson"),
            ]
        )
        yard = json.loads((work / "yard.geojson").read_text())
        flown = fly(work, yard)
        measured = measure(work, yard, flown)
    text = report(yard, flown, measured, log)
    args.out.write_text(text)
    print(text)
    return 0 if flown["state"] == "landed" else 1


if __name__ == "__main__":
    sys.exit(main())

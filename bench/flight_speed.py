"""Flights at 1, 5 and 10 m/s through the product, on the mock and on real ArduCopter SITL.

Every flight is `mvo-gcs fly SCENARIO --max-speed V` in its own process (the product
plans, reads the vehicles' limits, times the flight, refuses a speed it cannot keep safe
with exit 2, or flies it), against vehicles in other processes:

- mock: `python -m sitl_mock --scenario ... --track-log FILE` (one process, every vehicle
  at its UAV's start); the truth is the simulator's own track (10 samples per simulated
  second): separation of two vehicles both more than 1 m up, where each came down, and
  the mission time from the common start (the first vehicle leaving its hover point; a
  jerk-limited start needs 0.49 s to move the 2 cm that detects it, added back) to the
  last arrival within 0.5 m of a goal, on the simulator's clock.
- sitl: one ArduCopter SITL per UAV (tests/sitl/ardupilot_sitl.py), and the independent
  pymavlink observer on each autopilot's second port (tests/sitl/observer.py): the same
  measures, each vehicle on its own clock, its start when its mission passes the take-off
  item (tests/sitl/flown.py).

The yardstick is the product's own timed flight, `FlightPlan.duration_s`, which
`mvo-gcs fly` prints ("N s to the last goal"). Scenarios: case VI, the 10-UAV crossing
(seed 0), the six-UAV gap swap (seed 0), and generated crossing and random scenarios on
20 x 20 cells of 10 m (`--generated` seeds of each family, 6 to 12 UAVs). Every process
started here is stopped by its process id. Run in a loopback-only namespace (SITL
listens on every interface):

    unshare -n bash -c 'ip link set lo up; ARDUPILOT_SITL=/path/to/arducopter \\
        .venv/bin/python bench/flight_speed.py'
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from gcs.mission.geodesy import GridFrame  # noqa: E402
from planner.experiments.machine import describe_machine  # noqa: E402
from planner.experiments.scenario_generator import crossing_scenario, random_scenario  # noqa: E402
from planner.model.scenario import Scenario  # noqa: E402
from tests.sitl.ardupilot_sitl import stop_process  # noqa: E402
from tests.sitl.flown import (  # noqa: E402
    ARRIVAL_M,
    CANBERRA,
    gcs_separation,
    named,
    planned_s,
    speedup,
    two_r,
)

RESULTS = ROOT / "bench" / "results" / "flight_speed.md"
SPEEDS = (1.0, 5.0, 10.0)
GENERATED = (("crossing", 1, 6), ("random", 1, 8), ("crossing", 2, 8), ("random", 2, 12))
"""(family, seed, UAVs) in the order `--generated N` takes them, N per family."""
PLANNING = ("--time-budget", "0", "--seed", "1")
"""A plan of the planner's iterations alone (no wall-clock budget): the same plan for
every speed and both targets, and the same again on any machine."""
AIRBORNE_M = 1.0
MOVED_M = 0.02
MOVED_AFTER_S = (6 * MOVED_M / 1.0) ** (1 / 3)  # from rest at WP_JERK 1 m/s³
LANDED_RE = re.compile(r"^(\S+): landed ([\d.]+) m from its goal", re.M)
HIGHEST_RE = re.compile(r"highest speed it can keep safe is ([\d.]+) m/s")


@dataclass
class Result:
    target: str
    scenario: str
    uavs: int
    speed: float
    outcome: str  # "flown", "refused", "failed (exit N)"
    planned_s: float | None = None
    mission_s: float | None = None
    gcs_sep_m: float | None = None
    truth_sep_m: float | None = None
    two_r_m: float = 0.0
    gcs_landing_m: float | None = None  # worst, as `mvo-gcs fly` printed it
    truth_landing_m: float | None = None  # worst, by the truth / observer
    highest_safe_m_s: float | None = None
    wall_s: float = 0.0
    note: str = ""
    arrivals: dict[str, float | None] = field(default_factory=dict)

    @property
    def ratio(self) -> float | None:
        if self.mission_s is None or not self.planned_s:
            return None
        return self.mission_s / self.planned_s


def scenarios(generated: int) -> list[tuple[str, Scenario]]:
    chosen = [("case-6", named("case-6")), ("crossing-10", named("crossing-10"))]
    chosen.append(("gap-swap-6", named("gap-swap-6")))
    per_family: dict[str, int] = {}
    for family, seed, uavs in GENERATED:
        if per_family.get(family, 0) >= generated:
            continue
        per_family[family] = per_family.get(family, 0) + 1
        if family == "crossing":
            drawn = crossing_scenario(seed, uavs=uavs)
        else:
            drawn = random_scenario(seed, size=20, uavs=uavs, objects=2)
        chosen.append((f"{family}-s{seed}-{uavs}", drawn.model_copy(update={"origin": CANBERRA})))
    return chosen


def fly_command(source: Path, urls: list[str], speed: float, candidates: int = 1) -> list[str]:
    """`mvo-gcs fly` of the product in the working directory it runs in (this one, or an
    anchor's checkout: `python -m` imports from there first); with `candidates` above 1,
    the soonest-flown of that many seeds' plans (an option the anchor does not have)."""
    choice = ["--candidates", str(candidates)] if candidates > 1 else []
    return [
        sys.executable, "-m", "gcs.cli.main", "fly", str(source), "--vehicles", ",".join(urls),
        "--max-speed", f"{speed:g}", "--connect-timeout", "60", *PLANNING, *choice,
    ]  # fmt: skip


def read_cli(result: Result, fly: subprocess.CompletedProcess[str]) -> None:
    result.planned_s = planned_s(fly.stdout)
    result.gcs_sep_m = gcs_separation(fly.stdout)
    landed = [float(d) for _, d in LANDED_RE.findall(fly.stdout)]
    result.gcs_landing_m = max(landed) if landed else None
    if fly.returncode == 0:
        result.outcome = "flown"
    elif fly.returncode == 2 and "nothing was armed" in fly.stderr:
        result.outcome = "refused"
        found = HIGHEST_RE.search(fly.stderr)
        result.highest_safe_m_s = float(found.group(1)) if found else None
    else:
        result.outcome = f"failed (exit {fly.returncode})"
        result.note = (fly.stderr.strip().splitlines() or ["?"])[-1][:200]


# --- the mock ---------------------------------------------------------------------------


def fly_mock(
    name: str,
    scenario: Scenario,
    speed: float,
    rate: float,
    work: Path,
    product: Path = ROOT,
    target: str = "mock",
    candidates: int = 1,
) -> Result:
    """One flight of `product`'s `mvo-gcs fly` against this tree's mock."""
    work.mkdir(parents=True)
    source, track = work / "scenario.json", work / "track.jsonl"
    source.write_text(scenario.model_dump_json())
    result = Result(target, name, len(scenario.uavs), speed, "?", two_r_m=two_r(scenario))
    command = [
        sys.executable, "-m", "sitl_mock", "--scenario", str(source), "--base-port", "0",
        "--speedup", f"{rate:g}", "--track-log", str(track), "--estimate-delay", "5",
        "--position-delay", "2",
    ]  # fmt: skip
    began = time.monotonic()
    mock = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert mock.stdout is not None
        urls = [mock.stdout.readline().strip().split(": ", 1)[1] for _ in scenario.uavs]
        fly = subprocess.run(
            fly_command(source, urls, speed, candidates), cwd=product, capture_output=True,
            text=True,
            timeout=3600,
        )  # fmt: skip
    finally:
        stop_process(mock)
    result.wall_s = time.monotonic() - began
    (work / "fly.log").write_text(fly.stdout + "\n--- stderr\n" + fly.stderr)
    read_cli(result, fly)
    if result.outcome == "flown" or result.outcome.startswith("failed"):
        truth_from_track(result, scenario, track)
    return result


def truth_from_track(result: Result, scenario: Scenario, track: Path) -> None:
    rows = [json.loads(line) for line in track.read_text().splitlines() if line.strip()]
    if not rows:
        return
    sysids = sorted({r["sysid"] for r in rows})
    times = sorted({r["t"] for r in rows})
    index = {t: i for i, t in enumerate(times)}
    shape = (len(times), len(sysids))
    lat, lon, alt = np.full(shape, np.nan), np.full(shape, np.nan), np.full(shape, np.nan)
    for r in rows:
        i, k = index[r["t"]], sysids.index(r["sysid"])
        lat[i, k], lon[i, k], alt[i, k] = r["lat"], r["lon"], r["alt"]
    t = np.array(times)
    frame = GridFrame.of(scenario)
    ref_lat, ref_lon = float(lat[0, 0]), float(lon[0, 0])  # one origin for every vehicle
    lat0 = math.radians(ref_lat)
    north = (lat - ref_lat) * 111_320.0
    east = (lon - ref_lon) * 111_320.0 * math.cos(lat0)
    up = alt > AIRBORNE_M
    best = math.inf
    for a in range(len(sysids)):
        for b in range(a + 1, len(sysids)):
            both = up[:, a] & up[:, b]
            if both.any():
                d = np.hypot(north[both, a] - north[both, b], east[both, a] - east[both, b])
                best = min(best, float(d.min()))
    result.truth_sep_m = best if best < math.inf else None
    goals = [frame.to_geodetic(*u.goal) for u in scenario.uavs]
    gn = np.array([(float(g[0]) - ref_lat) * 111_320.0 for g in goals])
    ge = np.array([(float(g[1]) - ref_lon) * 111_320.0 * math.cos(lat0) for g in goals])
    to_goal = np.hypot(north - gn, east - ge)
    result.truth_landing_m = float(np.nanmax(to_goal[-1]))
    start = _common_start(t, north, east, alt)
    if start is None:
        return
    arrivals = {}
    for k, uav in enumerate(scenario.uavs):
        near = (t >= start) & (to_goal[:, k] <= ARRIVAL_M)
        arrivals[uav.id] = float(t[near][0] - start) if near.any() else None
    result.arrivals = arrivals
    if all(v is not None for v in arrivals.values()):
        result.mission_s = max(v for v in arrivals.values() if v is not None)


def _common_start(t: np.ndarray, north: np.ndarray, east: np.ndarray, alt: np.ndarray):
    """The first moment a vehicle hovering at its altitude leaves its hover point (less the
    time a jerk-limited start takes to move MOVED_M): the fleet's AUTO."""
    firsts = []
    for k in range(north.shape[1]):
        high = np.flatnonzero(alt[:, k] >= np.nanmax(alt[:, k]) - 0.5)
        if not len(high):
            continue
        h = high[0]
        moved = np.hypot(north[h:, k] - north[h, k], east[h:, k] - east[h, k]) > MOVED_M
        if moved.any():
            firsts.append(t[h + int(np.argmax(moved))])
    return min(firsts) - MOVED_AFTER_S if firsts else None


# --- real ArduCopter SITL -----------------------------------------------------------------


def fly_sitl(
    name: str, scenario: Scenario, speed: float, work: Path, candidates: int = 1
) -> Result:
    from tests.sitl.ardupilot_sitl import homes_at_starts, instances
    from tests.sitl.flown import flown
    from tests.sitl.observer import observing

    work.mkdir(parents=True)
    source = work / "scenario.json"
    source.write_text(scenario.model_dump_json())
    rate = speedup(scenario)
    result = Result("sitl", name, len(scenario.uavs), speed, "?", two_r_m=two_r(scenario))
    result.note = f"speed-up {rate:g}"
    began = time.monotonic()
    with instances(homes_at_starts(scenario), work, rate) as sitl:
        ports = [i.port for i in sitl]
        with observing(ports) as observer:
            fly = subprocess.run(
                fly_command(source, [i.connection for i in sitl], speed, candidates), cwd=ROOT,
                capture_output=True, text=True, timeout=3600,
            )  # fmt: skip
            measured = flown(observer, scenario) if fly.returncode != 2 else None
            tracks = {k: asdict(track) for k, track in observer.tracks.items()}
    (work / "observer.json").write_text(json.dumps(tracks))
    result.wall_s = time.monotonic() - began
    (work / "fly.log").write_text(fly.stdout + "\n--- stderr\n" + fly.stderr)
    note, result.note = result.note, ""
    read_cli(result, fly)
    result.note = f"{note}; {result.note}" if result.note else note
    if measured is not None:
        result.truth_sep_m = measured.separation_m
        result.truth_landing_m = max(measured.landed_m.values())
        result.mission_s = measured.mission_s
        result.arrivals = measured.arrival_s
    return result


# --- the report -----------------------------------------------------------------------------


def _m(value: float | None, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def table(results: list[Result]) -> list[str]:
    lines = [
        "| scenario | UAVs | m/s | outcome | timed s | mission s | mission / timed | "
        "GCS sep m | truth sep m | 2R m | GCS landing m | truth landing m | wall s |",
        "| --- | ---: | ---: | --- |" + " ---: |" * 9,
    ]
    for r in results:
        outcome = r.outcome
        if r.outcome == "refused":
            outcome = f"refused (highest safe {_m(r.highest_safe_m_s, 1)})"
        sep_flag = " **<2R**" if r.truth_sep_m is not None and r.truth_sep_m < r.two_r_m else ""
        ratio = r.ratio
        ratio_text = (
            "-" if ratio is None else f"{ratio:.2f}" + (" **>1.15**" if ratio > 1.15 else "")
        )
        lines.append(
            f"| {r.scenario} | {r.uavs} | {r.speed:g} | {outcome} | {_m(r.planned_s, 1)} | "
            f"{_m(r.mission_s, 1)} | {ratio_text} | {_m(r.gcs_sep_m)} | "
            f"{_m(r.truth_sep_m)}{sep_flag} | {r.two_r_m:.2f} | {_m(r.gcs_landing_m, 1)} | "
            f"{_m(r.truth_landing_m)} | {r.wall_s:.0f} |"
        )
    return lines


def gap_swap_lines(results: list[Result]) -> list[str]:
    """The gap swap at 5 m/s against 1 m/s: against the anchor (the product before this
    work, the issue's yardstick), then against this product's own 1 m/s flight."""
    lines = []
    now = next((r for r in results if _is(r, "mock", 5.0)), None)
    then = next((r for r in results if _is(r, "anchor", 1.0)), None)
    if now and then:
        lines += _share_line("against the anchor", now, then, "by the anchor")
    for target in ("mock", "sitl"):
        slow = next((r for r in results if _is(r, target, 1.0)), None)
        fast = next((r for r in results if _is(r, target, 5.0)), None)
        if slow and fast:
            timed = (fast.planned_s or 0) / (slow.planned_s or 1)
            lines += _share_line(
                target, fast, slow, "",
                f" (the product's own timed flights: {_m(fast.planned_s, 1)} s and "
                f"{_m(slow.planned_s, 1)} s, {timed:.0%})",
            )  # fmt: skip
    return lines or ["No flight at 1 m/s in this run to compare with."]


def _share_line(label: str, fast: Result, slow: Result, whose: str, more: str = "") -> list[str]:
    if fast.mission_s is None or slow.mission_s is None:
        return []
    share = fast.mission_s / slow.mission_s
    verdict = "under a quarter" if share < 0.25 else "NOT under a quarter"
    by = f" {whose}" if whose else ""
    return [
        f"- {label}: {fast.mission_s:.1f} s at 5 m/s against {slow.mission_s:.1f} s{by} at "
        f"1 m/s: {share:.0%} of the time, {verdict}{more}."
    ]


def _is(result: Result, target: str, speed: float) -> bool:
    return (result.target, result.scenario, result.speed) == (target, "gap-swap-6", speed)


def product_version() -> str:
    try:
        head = subprocess.run(
            ["git", "-C", str(ROOT), "describe", "--always", "--dirty"],
            capture_output=True, text=True, check=True,
        ).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    return head


def _candidates_line(candidates: int) -> list[str]:
    if candidates <= 1:
        return []
    return [
        f"Each product flight is the soonest of {candidates} candidate plans (`mvo-gcs fly "
        f"--candidates {candidates}`: seeds 1 to {candidates}, clearance 1.3 m and 0.5 m "
        "wider each, each timed at the flight's speed with the vehicles' own limits).",
        "",
    ]


def write(results: list[Result], out: Path, command: str, began: datetime, args) -> None:
    ended = datetime.now(UTC)
    uname = platform.uname()
    lines = [
        "# Flights at 1, 5 and 10 m/s: the mock and real ArduCopter SITL",
        "",
        f"Run {began:%Y-%m-%d %H:%M}-{ended:%H:%M} UTC on {describe_machine()}; "
        f"`uname -a`: {uname.system} {uname.node} {uname.release} {uname.version} "
        f"{uname.machine}. Other work was running on the machine. Product: "
        f"{args.product or product_version()}.",
        "",
        "```",
        command,
        "```",
        "",
        f"Generated scenarios: seeds per family {args.generated} (crossing and random, "
        "20 x 20 cells of 10 m). The mock ran at speed-up "
        f"{args.mock_speedup:g}; SITL at 5 for three vehicles and 2 for more (two cores).",
        "",
        *_candidates_line(args.candidates),
        "Columns: *timed* is the product's own timed flight (`FlightPlan.duration_s`, as "
        "`mvo-gcs fly` prints it, whole seconds); *mission* is the common start to the last "
        f"arrival within {ARRIVAL_M} m of a goal, by the truth (mock: the simulator's track; "
        "SITL: the independent observer, each vehicle on its own clock); *sep* the closest "
        "approach of two vehicles both more than 1 m up (GCS: from its telemetry, as "
        "printed; truth: the track or the observer); *landing* the worst distance from a "
        "goal once down. A refused speed is `mvo-gcs fly` exiting 2 before anything armed.",
        "",
    ]
    headings = {
        "mock": "mock",
        "sitl": "sitl",
        "anchor": f"anchor: `{args.anchor_label}` (the product before this work) on the mock",
    }
    for target, heading in headings.items():
        chosen = [r for r in results if r.target == target]
        if not chosen:
            continue
        lines += [f"## {heading}", "", *table(chosen), ""]
    refused = [r for r in results if r.outcome == "refused"]
    failed = [r for r in results if r.outcome.startswith("failed")]
    lines += ["## Refused speeds", ""]
    lines += [
        f"- {r.target} {r.scenario} at {r.speed:g} m/s: highest safe {_m(r.highest_safe_m_s, 1)}"
        for r in refused
    ] or ["None."]
    lines += ["", "## Failures", ""]
    lines += [
        f"- {r.target} {r.scenario} at {r.speed:g} m/s: {r.outcome}: {r.note}" for r in failed
    ]
    if not failed:
        lines.append("None.")
    lines += ["", "## The gap swap at 5 m/s against 1 m/s", "", *gap_swap_lines(results), ""]
    out.write_text("\n".join(lines) + "\n")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", default="mock,sitl")
    parser.add_argument("--speeds", default=",".join(f"{s:g}" for s in SPEEDS))
    parser.add_argument("--scenarios", default="", help="comma-separated names (default: all)")
    parser.add_argument(
        "--generated", default="mock=2,sitl=1", help="seeds per generated family, per target"
    )
    parser.add_argument("--mock-speedup", type=float, default=4.0)
    parser.add_argument(
        "--candidates",
        type=int,
        default=1,
        help="fly the soonest of this many candidate plans (`mvo-gcs fly --candidates`)",
    )
    parser.add_argument("--out", type=Path, default=RESULTS)
    parser.add_argument("--json", type=Path, default=None, help="also every result as JSON")
    parser.add_argument("--keep", type=Path, default=None, help="keep every flight's files here")
    parser.add_argument(
        "--product", default=None, help="what product was flown (default: git describe of here)"
    )
    parser.add_argument(
        "--anchor",
        type=Path,
        default=None,
        help="a checkout of the product before this work (git worktree add DIR 75873ab): "
        "its `mvo-gcs fly` at --anchor-speeds on the same mock and scenarios, side by side",
    )
    parser.add_argument("--anchor-speeds", default="1")
    parser.add_argument("--anchor-label", default="75873ab")
    args = parser.parse_args()
    began = datetime.now(UTC)
    command = "unshare -n bash -c 'ip link set lo up; ARDUPILOT_SITL=... .venv/bin/python " + (
        " ".join(["bench/flight_speed.py", *sys.argv[1:]]) + "'"
    )
    targets = args.targets.split(",")
    if "sitl" in targets and not os.environ.get("ARDUPILOT_SITL"):
        print("no ARDUPILOT_SITL: the mock only", file=sys.stderr)
        targets = [t for t in targets if t != "sitl"]
    speeds = [float(s) for s in args.speeds.split(",")]
    wanted = set(args.scenarios.split(",")) - {""}
    per_target = dict(item.split("=") for item in args.generated.split(","))
    results: list[Result] = []
    with tempfile.TemporaryDirectory(prefix="flight_speed_", dir=args.keep) as scratch:
        tmp = str(args.keep) if args.keep else scratch
        for target in targets:
            chosen = scenarios(int(per_target.get(target, 1)))
            chosen = [(n, s) for n, s in chosen if not wanted or n in wanted]
            for name, scenario in chosen:
                for speed in speeds:
                    work = Path(tmp) / f"{target}-{name}-{speed:g}"
                    if target == "mock":
                        result = fly_mock(
                            name, scenario, speed, args.mock_speedup, work,
                            candidates=args.candidates,
                        )  # fmt: skip
                    else:
                        result = fly_sitl(name, scenario, speed, work, args.candidates)
                    _record(result, results, args, command, began)
        if args.anchor:
            chosen = [(n, s) for n, s in scenarios(0) if not wanted or n in wanted]
            for name, scenario in chosen:
                for speed in (float(v) for v in args.anchor_speeds.split(",")):
                    work = Path(tmp) / f"anchor-{name}-{speed:g}"
                    result = fly_mock(
                        name, scenario, speed, args.mock_speedup, work, args.anchor, "anchor"
                    )
                    _record(result, results, args, command, began)
    print(f"wrote {args.out}")
    return 0


def _record(
    result: Result, results: list[Result], args: argparse.Namespace, command: str, began: datetime
) -> None:
    results.append(result)
    print(json.dumps(asdict(result)), flush=True)
    write(results, args.out, command, began, args)
    if args.json:
        args.json.write_text(json.dumps([asdict(r) for r in results], indent=1))


if __name__ == "__main__":
    sys.exit(main())

"""The planner on MovingAI benchmark maps (random, room, maze), beside pymapf's LaCAM and PP.

Maps and scenario files in `bench/maps/movingai/` (where they came from: its README.md):
`random-32-32-10`, `room-32-32-4` and `maze-32-32-2`, each with its `-random-1.scen`.
For each map and agent count N, the first N agents of the scenario file become one of
our scenarios, mapped plainly:

- a cell of the map is free where it holds '.' or 'G', blocked where it holds '@', 'O',
  'T', 'S' or 'W' (any other character is refused); x is the column, y the line of the
  map, as in the scenario file; 10 m cells, no non-UAV objects;
- each agent is a UAV flying from its start cell to its goal cell with the radius and
  speed the scale families use (the model's defaults: radius 0.3 cells, 1 cell/s).

Each scenario is run as `bench/planner_scale.py` runs a family (its `run_family`, one
seed, seed 0): ours (MVO `qos`, default settings, `--budget` s), LaCAM (its first
solution, the same limit) and pymapf's prioritized planning (PP, stopped at the limit
+ 1 s), every plan judged by our exact continuous-time check.

    PYTHONPATH=. .venv/bin/python bench/planner_movingai.py --agents 10,25,50,100 \\
        --budget 5 --out bench/results/planner_movingai.md

One setting of ours differs from the defaults: the safe start's hard limit
(`safe_start_limit_s`, `--limit` s from the plan's start; None by default), so that one
run cannot hold the benchmark for long; a plan refused at that limit counts as no safe
plan. Agent counts run in increasing order per map; once ours returned no safe plan or
took more than `--skip-after` seconds on a map, its larger counts are not run (said in
the results), and no run starts after `--stop-after` seconds of the whole benchmark.
"""

from __future__ import annotations

import argparse
import functools
import os
import shlex
import sys
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from bench.planner_scale import LACAM, Family, load, run_family
from planner.experiments.fleet_tables import OURS, Row, write_csv
from planner.experiments.machine import describe_machine
from planner.model.scenario import Scenario, load_scenario

MAPS_DIR = Path(__file__).parent / "maps" / "movingai"
MAPS = ["random-32-32-10", "room-32-32-4", "maze-32-32-2"]
FREE = frozenset(".G")
BLOCKED = frozenset("@OTSW")


@dataclass(frozen=True)
class Agent:
    start: tuple[int, int]
    goal: tuple[int, int]


def read_map(path: Path) -> tuple[int, int, list[tuple[int, int]]]:
    """Width, height and blocked cells (x = column, y = line) of a MovingAI .map file."""
    lines = path.read_text().splitlines()
    header = dict(line.split(maxsplit=1) for line in lines[:3])
    if lines[3].strip() != "map":
        raise ValueError(f"{path}: no 'map' line after the header")
    width, height = int(header["width"]), int(header["height"])
    rows = lines[4 : 4 + height]
    if len(rows) != height or any(len(row) != width for row in rows):
        raise ValueError(f"{path}: expected {height} lines of {width} characters")
    blocked = []
    for y, row in enumerate(rows):
        for x, char in enumerate(row):
            if char in BLOCKED:
                blocked.append((x, y))
            elif char not in FREE:
                raise ValueError(f"{path}: character {char!r} at ({x}, {y}) has no mapping")
    return width, height, blocked


def read_scen(path: Path, map_name: str) -> list[Agent]:
    """The agents of a MovingAI .scen file (version 1), in the file's order."""
    lines = path.read_text().splitlines()
    if lines[0].split() != ["version", "1"]:
        raise ValueError(f"{path}: not a version 1 scenario file")
    agents = []
    for line in lines[1:]:
        if not line.strip():
            continue
        fields = line.split("\t")
        if fields[1] != f"{map_name}.map":
            raise ValueError(f"{path}: a line for map {fields[1]!r}, not {map_name}.map")
        sx, sy, gx, gy = map(int, fields[4:8])
        agents.append(Agent((sx, sy), (gx, gy)))
    return agents


def movingai_scenario(map_name: str, agents: int) -> Scenario:
    """Our scenario of the first `agents` agents of `<map>-random-1.scen` on `<map>.map`."""
    width, height, blocked = read_map(MAPS_DIR / f"{map_name}.map")
    chosen = read_scen(MAPS_DIR / f"{map_name}-random-1.scen", map_name)[:agents]
    if len(chosen) < agents:
        raise ValueError(f"{map_name}: the scenario file has only {len(chosen)} agents")
    return load_scenario(
        {
            "name": f"{map_name}-random-1-{agents}",
            "grid": {"width": width, "height": height, "cell_size_m": 10.0},
            "uavs": [
                {"id": f"uav{k + 1}", "start": list(a.start), "goal": list(a.goal)}
                for k, a in enumerate(chosen)
            ],
            "obstacles": [list(c) for c in blocked],
            "non_uav_objects": [],
        },
        max_uavs=agents,
    )


def scenario_for_seed(map_name: str, agents: int, seed: int) -> Scenario:
    """`movingai_scenario` as a family builds it (the seed does not change it)."""
    return movingai_scenario(map_name, agents)


def family_name(map_name: str, agents: int) -> str:
    return f"{map_name}, {agents} agents"


def cells(row: Row | None, ours: bool = False) -> list[str]:
    """Safe?, (ours: s to first safe,) s, length ratio of one run; '-' where none."""
    if row is None:
        return ["not run"] + ["-"] * (3 if ours else 2)
    safe = "yes" if row.feasible else "no"
    ratio = f"{row.length_ratio:.3f}" if row.length_ratio is not None else "-"
    if ours:
        first = f"{row.first_safe_s:.2f}" if row.first_safe_s is not None else "-"
        return [safe, first, f"{row.seconds:.2f}", ratio]
    return [safe, f"{row.seconds:.2f}", ratio]


def pick(rows: list[Row], name: str) -> Row | None:
    """The row of planner `name` ("PP": pymapf's prioritized planning), if it ran."""
    for r in rows:
        if r.planner == name or (name == "PP" and r.planner.startswith("prioritized")):
            return r
    return None


def table(rows: list[Row], plan: list[tuple[str, int]]) -> list[str]:
    lines = [
        "| map | agents | ours safe | ours s to first safe | ours s total | ours ratio | "
        "LaCAM safe | LaCAM s | LaCAM ratio | PP safe | PP s | PP ratio |",
        "|---|---:|---|---:|---:|---:|---|---:|---:|---|---:|---:|",
    ]
    for map_name, agents in plan:
        mine = [r for r in rows if r.family == family_name(map_name, agents)]
        row = [
            *cells(pick(mine, OURS), ours=True),
            *cells(pick(mine, LACAM)),
            *cells(pick(mine, "PP")),
        ]
        lines.append(f"| {map_name} | {agents} | " + " | ".join(row) + " |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", default=",".join(MAPS))
    parser.add_argument("--agents", default="10,25,50,100", help="comma-separated counts")
    parser.add_argument("--budget", type=float, default=5.0)
    parser.add_argument("--limit", type=float, default=120.0, help="ours' safe_start_limit_s")
    parser.add_argument("--skip-after", type=float, default=60.0)
    parser.add_argument("--stop-after", type=float, default=900.0)
    parser.add_argument("--out", type=Path, default=Path("bench/results/planner_movingai.md"))
    args = parser.parse_args()
    maps = [m.strip() for m in args.maps.split(",") if m.strip()]
    counts = sorted({int(n) for n in args.agents.split(",") if n.strip()})
    plan = [(m, n) for m in maps for n in counts]
    command = "PYTHONPATH=. .venv/bin/python " + shlex.join(sys.argv)
    started, clock, loads_before = datetime.now(UTC), time.perf_counter(), os.getloadavg()
    rows: list[Row] = []
    skipped: list[str] = []
    loads: list[str] = []
    for map_name in maps:
        slow = False
        for agents in counts:
            name = family_name(map_name, agents)
            if slow or time.perf_counter() - clock > args.stop_after:
                skipped.append(
                    f"{name}: not run ("
                    + (
                        "ours had no safe plan, or took over "
                        f"{args.skip_after:g} s, on fewer agents"
                        if slow
                        else f"the benchmark had run {args.stop_after:g} s"
                    )
                    + ")"
                )
                continue
            build = functools.partial(scenario_for_seed, map_name, agents)
            family = Family(name, build, dense=True)
            before = load()
            done = run_family(family, 1, args.budget, pp=True, safe_start_limit_s=args.limit)
            rows += done
            loads.append(f"{name}: {before:.2f} / {load():.2f}")
            ours = next(r for r in done if r.planner == OURS)
            slow = not ours.feasible or ours.seconds > args.skip_after
    finished, loads_after = datetime.now(UTC), os.getloadavg()
    csv_path = args.out.with_suffix(".csv")
    write_csv(rows, csv_path)
    lines = [
        "# The planner on MovingAI benchmark maps, beside LaCAM and PP\n",
        f"- Run {started:%Y-%m-%d %H:%M}-{finished:%H:%M} UTC on {describe_machine()}. "
        f"Load averages (1, 5, 15 min) {' / '.join(f'{x:.2f}' for x in loads_before)} at "
        f"the start, {' / '.join(f'{x:.2f}' for x in loads_after)} at the end; the machine "
        "is shared with other work.",
        f"- Command: `{command}`. One planner at a time in one process.",
        "- Maps and scenarios: MovingAI's MAPF benchmark (Sturtevant, \"Benchmarks for "
        'Grid-Based Pathfinding", IEEE TCIAIG 2012; movingai.com), the first N agents of '
        "each map's `-random-1.scen`; files and their sources in "
        "[bench/maps/movingai/](../maps/movingai/README.md).",
        "- Mapping: '.' and 'G' free, '@', 'O', 'T', 'S', 'W' blocked (these three maps hold "
        "only '.' and '@'); each agent a UAV from its start cell to its goal cell, radius "
        "0.3 cells, 1 cell/s, 10 m cells, no non-UAV objects (as `bench/planner_scale.py`'s "
        "families).",
        f"- Ours: MVO `qos`, default settings, time budget {args.budget:g} s (it bounds only "
        "the improvement), seed 0; one setting changed: the safe start's hard limit "
        f"`safe_start_limit_s` = {args.limit:g} s (None by default: the safe start then runs "
        "to its end), a plan refused at it counted as no safe plan. LaCAM: pymapf 0.9.0, its "
        f"first solution, time limit {args.budget:g} s, 4-connected. PP: pymapf's "
        f"prioritized planning, stopped at {args.budget + 1:g} s. Runs by "
        "`bench/planner_scale.py`'s `run_family`.",
        "- Every plan judged by our exact continuous-time check (safe = no conflict between "
        "discs of radius 0.3 in continuous time, every UAV on its goal, never faster than its "
        "speed). Length ratio: total length over the sum of each UAV's 8-connected shortest "
        "path alone (below 1: any-angle). Times: wall seconds until the plan was returned "
        "(LaCAM and PP: shown also when they failed); one run each.\n",
        *table(rows, plan),
        "",
        "Load average (1 minute) before / after each scenario: " + "; ".join(loads) + ".",
        "",
        *(["Not run:\n", *(f"- {s}" for s in skipped), ""] if skipped else []),
        f"Per-run rows (with each planner's note): `{csv_path.name}`.",
        "",
    ]
    args.out.write_text("\n".join(lines))
    print(args.out.read_text())


if __name__ == "__main__":
    main()

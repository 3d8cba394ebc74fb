"""What every command that plans takes from the command line: a scenario (a grid, or
a geographic one in GeoJSON) and the planner's settings. Shared by `mvo-gcs plan` and
`mvo-gcs fly`."""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from gcs.mission.area_imports import from_kml
from gcs.mission.geodesy import GridFrame
from gcs.mission.geographic import GeographicError, derive_file, looks_geographic
from planner.cases import CASES, load_case
from planner.model.scenario import Scenario, load_scenario, max_planned_uavs
from planner.optimizers import ALGORITHMS
from planner.pipeline import PlannerSettings


class ScenarioFileError(ValueError):
    """The scenario file is missing, unreadable or invalid."""


def positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def add_planning_arguments(parser: argparse.ArgumentParser, iterations: int = 1000) -> None:
    parser.add_argument(
        "scenario",
        help="scenario JSON file, geographic scenario (.geojson or .kml, docs/planner.md), "
        "or case-1 .. case-6",
    )
    parser.add_argument("--algorithm", choices=sorted(ALGORITHMS), default="mvo")
    parser.add_argument("--objective", choices=["qos", "paper"], default="qos")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--population", type=positive_int, default=30)
    parser.add_argument("--iterations", type=positive_int, default=iterations)
    parser.add_argument(
        "--time-budget",
        type=float,
        default=5.0,
        metavar="SECONDS",
        help="wall time for the plan (default 5); 0: none, iterations only (deterministic)",
    )
    parser.add_argument(
        "--patience",
        type=int,
        default=100,
        metavar="ITERATIONS",
        help="a run stops after this many iterations without gain (default 100); "
        "0: every run does all of its iterations",
    )


def planner_settings(args: argparse.Namespace) -> PlannerSettings:
    return PlannerSettings(
        algorithm=args.algorithm,
        objective=args.objective,
        seed=args.seed,
        population=args.population,
        iterations=args.iterations,
        time_budget_s=args.time_budget if args.time_budget > 0 else None,
        patience=args.patience if args.patience > 0 else None,
    )


def read_scenario(source: str) -> Scenario:
    """A scenario file, or the name of one of the paper's cases (case-1 .. case-6)."""
    return read_scenario_file(source).scenario


@dataclass(frozen=True)
class ScenarioFile:
    scenario: Scenario
    frame: GridFrame | None = None
    """Where the grid lies, for a geographic scenario (GeoJSON) the grid was derived from."""


def read_scenario_file(source: str) -> ScenarioFile:
    """A grid scenario file, a geographic one (a GeoJSON FeatureCollection, made into its
    grid), or the name of one of the paper's cases."""
    path = Path(source)
    if not path.exists() and source in CASES:
        return ScenarioFile(load_case(source))
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
        raise ScenarioFileError(f"cannot read scenario {source}: {reason}") from exc
    try:
        suffix = path.suffix.lower()
        if suffix == ".kml" or suffix == ".geojson" or looks_geographic(_json_or_none(text)):
            derived = derive_file(from_kml(text) if suffix == ".kml" else text)
            return ScenarioFile(derived.scenario, derived.frame)
        return ScenarioFile(load_scenario(text, max_uavs=max_planned_uavs()))
    except ValidationError as exc:
        raise ScenarioFileError(f"{source} is not a valid scenario:\n{_describe(exc)}") from exc
    except GeographicError as exc:
        raise ScenarioFileError(f"{source} is not a plannable scenario: {exc}") from exc


def _json_or_none(text: str) -> Any:
    try:
        return json.loads(text)
    except ValueError:
        return None  # the scenario's own parser says where it breaks


def _describe(exc: ValidationError) -> str:
    lines = []
    for error in exc.errors():
        where = ".".join(str(p) for p in error["loc"]) or "scenario"
        lines.append(f"  {where}: {error['msg'].removeprefix('Value error, ')}")
    return "\n".join(lines)

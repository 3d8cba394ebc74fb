"""`mvo-gcs`: the command line of the product."""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from gcs.cli.planning_options import (
    ScenarioFileError,
    add_planning_arguments,
    planner_settings,
    positive_int,
    read_scenario_file,
)
from gcs.mission.area_imports import from_kml, from_plan_files
from gcs.mission.geographic import GeographicError, derive_file, wgs84_trajectories
from planner.cases import CASES, PAPER_POPULATIONS
from planner.optimizers import ALGORITHMS, ObjectiveError, OptimizerInputError

EXPERIMENTS_HINT = (
    "pip install 'mvo-gcs[experiments]' (from a checkout: pip install -e '.[experiments]')"
)


class MissingDependency(Exception):
    """A command needs an optional dependency that is not installed."""


class StorageRefused(Exception):
    """The service's database cannot be used by this version (a newer one migrated it)."""


USER_ERRORS = (
    OptimizerInputError,
    ObjectiveError,
    ScenarioFileError,
    MissingDependency,
    StorageRefused,
)
"""Errors a user can cause: reported in one line, exit code 2, no traceback."""


def _experiments(module: str) -> Any:
    """A module of `planner.experiments`, whose plotting and cluster libraries are the
    optional 'experiments' extra (the service and the planner do not need them)."""
    try:
        return importlib.import_module(f"planner.experiments.{module}")
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split(".")[0] in ("matplotlib", "tqdm", "dask", "distributed"):
            raise MissingDependency(f"this command needs {exc.name}: {EXPERIMENTS_HINT}") from exc
        raise


def _add_executor_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--workers",
        type=positive_int,
        default=None,
        help="local worker processes (default: one per core)",
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="run on this Dask scheduler (e.g. tcp://127.0.0.1:8786) instead of a local pool",
    )


def _reproduce_benchmarks(args: argparse.Namespace) -> int:
    study = _experiments("benchmark_study")
    config = study.StudyConfig(
        seeds=args.seeds,
        figure_seeds=min(args.seeds, 10),
        iterations=args.iterations,
        tolerances=tuple(args.tolerance),
        quick=args.quick,
        algorithms=tuple(args.algorithms),
    )
    report = study.run_study(config, args.out, workers=args.workers, scheduler=args.scheduler)
    print(f"wrote {report}")
    return 0


def _reproduce_cases(args: argparse.Namespace) -> int:
    study = _experiments("case_study")
    config = study.CaseStudyConfig(
        seeds=args.seeds,
        iterations=args.iterations,
        populations=tuple(dict.fromkeys(args.populations)),
        algorithms=tuple(dict.fromkeys(args.algorithms)),
        objective=args.objective,
        cases=tuple(dict.fromkeys(args.cases)),
    )
    report = study.run_case_study(config, args.out, workers=args.workers, scheduler=args.scheduler)
    print(f"wrote {report}")
    return 0


def _bench_optimizers(args: argparse.Namespace) -> int:
    comparison = _experiments("library_comparison")
    config = comparison.ComparisonConfig(
        seeds=args.seeds,
        iterations=args.iterations,
        population=args.population,
        dim=args.dim,
        algorithms=tuple(args.algorithms),
    )
    try:
        out = comparison.run_comparison(config, args.out)
    except comparison.BenchDependencyError as exc:
        raise MissingDependency(str(exc)) from exc
    print(f"wrote {out}")
    return 0


def _plan(args: argparse.Namespace) -> int:
    from planner.pipeline import plan

    source = read_scenario_file(args.scenario)
    scenario = source.scenario
    result = plan(scenario, planner_settings(args))
    text = result.model_dump_json(indent=2)
    if source.frame is not None:  # a geographic scenario: its paths in WGS84 too
        answer = result.model_dump(mode="json")
        answer["trajectories_wgs84"] = wgs84_trajectories(source.frame, result)
        text = json.dumps(answer, indent=2)
    if args.output:
        args.output.write_text(text + "\n")
    else:
        print(text)
    m = result.metrics
    summary = (
        f"{scenario.name}: {'feasible' if result.feasible else 'NOT feasible'}, "
        f"{m.conflicts} conflicts, total length {m.total_length:.2f} cells, "
        f"mean deviation {m.mean_deviation:.2f}, {m.nfe} evaluations, {m.seconds:.2f} s"
    )
    print(summary, file=sys.stderr)
    if m.first_safe_s is not None:
        print(f"  first safe plan after {m.first_safe_s:.2f} s", file=sys.stderr)
    if m.complete_start is not None:  # the safe start needed the whole fleet searched at once
        print(f"  complete start: {m.complete_start}", file=sys.stderr)
    for conflict in result.conflicts:
        print(f"  conflict: {conflict['message']}", file=sys.stderr)
    return 0 if result.feasible else 1


def _import(args: argparse.Namespace) -> int:
    """.plan files or one KML to a geographic scenario, checked by deriving its grid."""
    kml = [f for f in args.files if f.suffix.lower() == ".kml"]
    try:
        if kml:
            if len(args.files) > 1:
                raise ScenarioFileError("give one KML file, or .plan files only")
            data = from_kml(_read_bytes(kml[0]), args.cell_size)
        elif args.cell_size is None:
            raise ScenarioFileError(".plan files need --cell-size")
        else:
            data = from_plan_files(args.files, args.cell_size, args.name)
        if args.name:
            data["properties"]["name"] = args.name
        scenario = derive_file(data).scenario
    except GeographicError as exc:
        raise ScenarioFileError(f"cannot import: {exc}") from exc
    except ValidationError as exc:
        raise ScenarioFileError(f"cannot import: {exc.errors()[0]['msg']}") from exc
    text = json.dumps(data, indent=2) + "\n"
    if args.output:
        args.output.write_text(text)
    else:
        print(text, end="")
    size = f"{scenario.grid.width} x {scenario.grid.height}"
    print(f"{scenario.name}: {len(scenario.uavs)} UAVs on {size} cells", file=sys.stderr)
    return 0


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise ScenarioFileError(f"cannot read {path}: {exc.strerror}") from exc


def _bench_planner(args: argparse.Namespace) -> int:
    bench = _experiments("planner_bench")
    config = bench.PlannerBenchConfig(
        scenarios=args.scenarios,
        first_seed=args.first_seed,
        algorithm=args.algorithm,
        population=args.population,
        iterations=args.iterations,
        workers=args.workers,
    )
    print(f"wrote {bench.run_planner_bench(config, args.out)}")
    return 0


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The whole command line; of the commands whose options live in their own module,
    only `command`'s module is imported (so `--help` and `plan` load no server)."""
    parser = argparse.ArgumentParser(
        prog="mvo-gcs", description="MVO multi-UAV path planning and ground station"
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    reproduce = commands.add_parser("reproduce", help="reproduce the paper's tables and figures")
    studies = reproduce.add_subparsers(dest="study", required=True, metavar="STUDY")
    bench_fns = studies.add_parser(
        "benchmarks",
        help="Table II (NFE to the optimum) and Fig. 1 (convergence) on benchmark functions",
    )
    bench_fns.add_argument("--out", type=Path, required=True, help="output directory")
    bench_fns.add_argument("--seeds", type=positive_int, default=30)
    bench_fns.add_argument("--iterations", type=positive_int, default=1000)
    bench_fns.add_argument(
        "--tolerance",
        type=float,
        nargs="+",
        default=[1e-8, 1e-2],
        help="a run reaches the optimum when its best cost is within this of it; "
        "one Table II per value, the first is the headline (default: 1e-8 1e-2)",
    )
    bench_fns.add_argument(
        "--quick", action="store_true", help="a smaller Fig. 1 grid (fewer dimensions and sizes)"
    )
    bench_fns.add_argument(
        "--algorithms", nargs="+", choices=sorted(ALGORITHMS), default=list(ALGORITHMS)
    )
    _add_executor_options(bench_fns)
    bench_fns.set_defaults(handler=_reproduce_benchmarks)

    cases = studies.add_parser(
        "cases",
        help="Table III and Figs. 3-5: the paper's six cases planned by every algorithm",
    )
    cases.add_argument("--out", type=Path, required=True, help="output directory")
    cases.add_argument("--seeds", type=positive_int, default=30)
    cases.add_argument("--iterations", type=positive_int, default=1000)
    cases.add_argument(
        "--populations", type=positive_int, nargs="+", default=list(PAPER_POPULATIONS)
    )
    cases.add_argument(
        "--algorithms", nargs="+", choices=sorted(ALGORITHMS), default=list(ALGORITHMS)
    )
    cases.add_argument(
        "--objective",
        choices=["paper", "qos"],
        default="paper",
        help="eq. (10) as in the paper (default), or the product's qos objective",
    )
    cases.add_argument(
        "--cases", nargs="+", choices=CASES, default=list(CASES), help="default: all six"
    )
    _add_executor_options(cases)
    cases.set_defaults(handler=_reproduce_cases)

    plan = commands.add_parser(
        "plan", help="plan collision-free paths for a scenario; exit 1 if no safe plan"
    )
    add_planning_arguments(plan)
    plan.add_argument("-o", "--output", type=Path, help="write the plan here (default: stdout)")
    plan.set_defaults(handler=_plan)

    imports = commands.add_parser(
        "import",
        help="make QGroundControl .plan files (one per UAV) or a KML file into a geographic "
        "scenario (GeoJSON, docs/planner.md)",
    )
    imports.add_argument("files", nargs="+", type=Path, metavar="FILE")
    imports.add_argument(
        "--cell-size", type=float, metavar="METRES", help="grid cell size (a KML may hold it)"
    )
    imports.add_argument("--name", help="the scenario's name (default: the files' names)")
    imports.add_argument("-o", "--output", type=Path, help="write here (default: stdout)")
    imports.set_defaults(handler=_import)

    bench = commands.add_parser("bench", help="speed benchmarks (results under bench/)")
    benches = bench.add_subparsers(dest="bench", required=True, metavar="BENCH")
    libs = benches.add_parser(
        "optimizers",
        help="our six optimizers against mealpy and EvoloPy (needs the 'bench' extra)",
    )
    libs.add_argument("--out", type=Path, default=Path("bench/results/optimizers.md"))
    libs.add_argument("--seeds", type=positive_int, default=10)
    libs.add_argument("--iterations", type=positive_int, default=1000)
    libs.add_argument("--population", type=positive_int, default=30)
    libs.add_argument("--dim", type=positive_int, default=30)
    libs.add_argument(
        "--algorithms", nargs="+", choices=sorted(ALGORITHMS), default=list(ALGORITHMS)
    )
    libs.set_defaults(handler=_bench_optimizers)

    paths = benches.add_parser(
        "planner", help="the path planner's targets: six cases, speed, 100 generated scenarios"
    )
    paths.add_argument("--out", type=Path, default=Path("bench/results/planner.md"))
    paths.add_argument("--scenarios", type=positive_int, default=100)
    paths.add_argument("--first-seed", type=int, default=0)
    paths.add_argument("--algorithm", choices=sorted(ALGORITHMS), default="mvo")
    paths.add_argument("--population", type=positive_int, default=30)
    paths.add_argument("--iterations", type=positive_int, default=1000)
    paths.add_argument(
        "--workers",
        type=positive_int,
        default=None,
        help="processes for the generated scenarios (timed sections always run alone)",
    )
    paths.set_defaults(handler=_bench_planner)
    _add_module_commands(commands, command)
    return parser


MODULE_COMMANDS = {
    "sitl": ("sitl_mock.cli", "run simulated MAVLink vehicles (ArduCopter or PX4 flavour)"),
    "fly": ("gcs.cli.fly", "plan a scenario, upload it to vehicles and fly it"),
    "serve": ("gcs.cli.serve", "run the planning service (REST + WebSocket)"),
    "demo": ("gcs.cli.demo", "run the service with mock vehicles, ready for case VI"),
}
"""Commands whose options live beside their code: each module has `add_arguments(parser)`
and `run(args) -> int`."""


def _add_module_commands(
    commands: argparse._SubParsersAction[argparse.ArgumentParser], chosen: str | None
) -> None:
    for name, (module_name, help_text) in MODULE_COMMANDS.items():
        sub = commands.add_parser(name, help=help_text, description=help_text)
        if name == chosen:
            module = importlib.import_module(module_name)
            module.add_arguments(sub)
            sub.set_defaults(handler=module.run)


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(next((a for a in argv if not a.startswith("-")), None))
    args = parser.parse_args(argv)
    try:
        code: int = args.handler(args)
        return code
    except USER_ERRORS as exc:
        parser.exit(2, f"{parser.prog}: error: {exc}\n")
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())

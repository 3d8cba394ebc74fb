"""The architecture's dependency rules (docs/ARCHITECTURE.md), read from the source.

The rules are import-linter contracts in `pyproject.toml` (`[tool.importlinter]`): gcs
above planner and sitl_mock, which import neither of the others; the planner free of
MAVLink, HTTP, storage and geography; the five layers of gcs and the planner's seven;
only the command line starting simulated vehicles; the planner's adapters (`references`,
`experiments`) imported by nothing else in the planner; no import cycles, type-only ones
included.
`lint-imports` checks every import in the source (inside functions and under
TYPE_CHECKING too); these tests run it, on the source and on a tiny tree that breaks
each contract in turn. Beside them, a check that import-linter has no contract for:
no module imports another module's private (underscore) names.
"""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("gcs", "planner", "sitl_mock")
CONTRACTS = {
    c["id"]: c["name"]
    for c in tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"][
        "contracts"
    ]
}


def lint_imports(where: Path) -> subprocess.CompletedProcess[str]:
    """`lint-imports` on the packages importable from `where`, by its pyproject.toml."""
    command = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    assert command, "lint-imports is missing: pip install -e '.[test]'"
    env = {**os.environ, "PYTHONPATH": str(where)}
    return subprocess.run(
        [command, "--no-logo", "--no-cache"],
        cwd=where,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def broken(output: str) -> set[str]:
    """The ids of the contracts `lint-imports` reported broken."""
    flat = " ".join(output.split())
    return {key for key, name in CONTRACTS.items() if f"{name} BROKEN" in flat}


def test_the_contracts_hold() -> None:
    result = lint_imports(ROOT)
    assert result.returncode == 0, result.stdout + result.stderr


# A tiny tree with the packages' names and layers, kept by every contract; each case adds
# one file (path, text) that breaks the contracts named.
TINY = {
    "gcs/__init__.py": "",
    "gcs/cli/__init__.py": "import gcs.service\nimport sitl_mock\nimport planner.experiments\n",
    "gcs/service/__init__.py": "",
    "gcs/fleet/__init__.py": "",
    "gcs/mission/__init__.py": "import gcs.mavlink\nimport planner\n",
    "gcs/mavlink/__init__.py": "",
    "planner/__init__.py": "",
    "planner/pipeline.py": "import planner.live\nimport planner.flows\n",
    "planner/live/__init__.py": "import planner.flows\n",
    "planner/flows/__init__.py": "import planner.search\nimport planner.optimizers\n",
    "planner/search/__init__.py": "import planner.check\n",
    "planner/check/__init__.py": "import planner.geometry\n",
    "planner/optimizers/__init__.py": "import numpy\n",
    "planner/geometry/__init__.py": "import planner.model\n",
    "planner/cases/__init__.py": "import planner.model\n",
    "planner/model/__init__.py": "",
    "planner/references/__init__.py": "import planner.pipeline\n",
    "planner/experiments/__init__.py": "import planner.references\n",
    "sitl_mock/__init__.py": "import pymavlink\n",
}
BREAKS = {
    "planner imports gcs": ("planner/bad.py", "import gcs.mavlink\n", {"packages"}),
    "sitl_mock imports planner": ("sitl_mock/bad.py", "import planner\n", {"packages"}),
    "planner speaks MAVLink": ("planner/bad.py", "import pymavlink\n", {"planner-alone"}),
    "mavlink imports the fleet": (
        "gcs/mavlink/bad.py",
        "def late():\n    import gcs.fleet\n",
        {"gcs-layers"},
    ),
    "a gcs module outside the layers": ("gcs/extra.py", "", {"gcs-layers"}),
    "the service starts vehicles": (
        "gcs/service/bad.py",
        "import sitl_mock\n",
        {"simulated-vehicles"},
    ),
    "the planner's model imports an optimizer": (
        "planner/model/bad.py",
        "import planner.optimizers\n",
        {"planner-layers"},
    ),
    "the planner core imports a reference": (
        "planner/bad.py",
        "from planner.references import judge\n",
        {"planner-adapters"},
    ),
    "a type-only cycle": (
        "planner/experiments/report.py",
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from planner.experiments.study import Config\n",
        {"no-cycles"},
    ),
}


def tiny_tree(where: Path, extra: dict[str, str]) -> Path:
    for name, text in {**TINY, **extra}.items():
        (where / name).parent.mkdir(parents=True, exist_ok=True)
        (where / name).write_text(text)
    shutil.copy(ROOT / "pyproject.toml", where / "pyproject.toml")
    return where


def test_the_tiny_tree_keeps_every_contract(tmp_path: Path) -> None:
    result = lint_imports(tiny_tree(tmp_path, {}))
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize("case", sorted(BREAKS))
def test_each_contract_can_fail(tmp_path: Path, case: str) -> None:
    path, text, contracts = BREAKS[case]
    extra = {path: text}
    if case == "a type-only cycle":
        extra["planner/experiments/study.py"] = "from planner.experiments.report import x\n"
    result = lint_imports(tiny_tree(tmp_path, extra))
    assert result.returncode == 1 and broken(result.stdout) == contracts, result.stdout


def test_every_contract_is_shown_failing() -> None:
    assert set().union(*(c for _, _, c in BREAKS.values())) == set(CONTRACTS)


# --- private names ----------------------------------------------------------------------

# Imports of another module's private names still allowed, each with the issue that
# removes it. Nothing else may be added here: a name used across modules is public.
ALLOWED_PRIVATE: set[tuple[str, str]] = set()


def modules(package: str) -> dict[str, Path]:
    found = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


ALL = {name: path for package in PACKAGES for name, path in modules(package).items()}


def private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def dotted(node: ast.expr) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        base = dotted(node.value)
        return None if base is None else f"{base}.{node.attr}"
    return None


def private_uses(name: str, source: str, is_package: bool = False) -> Iterator[str]:
    """The private names of other project modules that module `name` imports or reads,
    as `module._name`: `from m import _x`, `import m._x`, and `m._x` on an imported m."""
    package = name if is_package else name.rpartition(".")[0]
    bound: dict[str, str] = {}  # local name -> the project module it stands for
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] in PACKAGES and any(map(private, parts)) and alias.name != name:
                    yield alias.name
                if alias.asname:
                    bound[alias.asname] = alias.name
                else:
                    bound[parts[0]] = parts[0]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            for alias in node.names:
                target = f"{base}.{alias.name}"
                if base.split(".")[0] not in PACKAGES:
                    continue
                if private(alias.name) and base != name:
                    yield target
                if target in ALL:  # a module imported by name: its attributes are read
                    bound[alias.asname or alias.name] = target
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and private(node.attr):
            reader = dotted(node.value)
            if reader is None:
                continue
            head, _, rest = reader.partition(".")
            module = bound.get(head)
            if module is None:
                continue
            module = f"{module}.{rest}" if rest else module
            if module in ALL and module != name:
                yield f"{module}.{node.attr}"


def test_no_module_uses_another_modules_private_names() -> None:
    found = {
        (name, used)
        for name, path in ALL.items()
        for used in private_uses(name, path.read_text(), path.name == "__init__.py")
    }
    unexpected = sorted(found - ALLOWED_PRIVATE)
    assert not unexpected, "private names used across modules (make them public):\n" + "\n".join(
        f"  {name} uses {used}" for name, used in unexpected
    )
    stale = sorted(ALLOWED_PRIVATE - found)
    assert not stale, f"no longer used, take them off ALLOWED_PRIVATE: {stale}"


def test_the_private_check_catches_imports_and_attributes() -> None:
    source = (
        "from planner.flows.planning import _Best, PlannerSettings\n"
        "from planner.flows import planning\n"
        "from . import _Map\n"
        "import planner.search.space_time as st\n"
        "import gcs.mavlink.link\n"
        "def f(self):\n"
        "    planning._finish(); st._OutOfTime; gcs.mavlink.link._private; self._own\n"
    )
    assert set(private_uses("planner.flows.anytime", source)) == {
        "planner.flows.planning._Best",
        "planner.flows._Map",
        "planner.flows.planning._finish",
        "planner.search.space_time._OutOfTime",
        "gcs.mavlink.link._private",
    }
    own = (
        "from planner.flows.planning import _Best\n"
        "import planner.flows.planning\n"
        "planner.flows.planning._Map\n"
    )
    assert not set(private_uses("planner.flows.planning", own))
    assert not set(private_uses("planner.x", "from planner import __version__\nimport os._x\n"))

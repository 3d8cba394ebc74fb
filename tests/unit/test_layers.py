"""The architecture's dependency rules (docs/ARCHITECTURE.md), read from the source.

Every `import` and `from ... import` in the three packages is parsed, at any depth
(inside functions too), and checked against the layering: a layer of `gcs` imports only
layers below it, `planner` and `sitl_mock` import neither of the others, only the
command line starts simulated vehicles, and no module imports itself in a cycle.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
GCS_LAYERS = ("gcs.mavlink", "gcs.mission", "gcs.fleet", "gcs.service", "gcs.cli")


def modules(package: str) -> dict[str, Path]:
    found = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found[name] = path
    return found


ALL = {**modules("gcs"), **modules("planner"), **modules("sitl_mock")}


def imports(name: str, path: Path, *, runtime_only: bool = False) -> Iterator[str]:
    """Absolute names of what `name` imports (`runtime_only`: not under TYPE_CHECKING)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(), str(path))
    typing_only = {
        id(inner)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and ast.unparse(node.test).endswith("TYPE_CHECKING")
        for inner in ast.walk(node)
    }
    for node in ast.walk(tree):
        if runtime_only and id(node) in typing_only:
            continue
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            yield base
            yield from (f"{base}.{alias.name}" for alias in node.names)


def project_imports(name: str, *, runtime_only: bool = False) -> set[str]:
    found = imports(name, ALL[name], runtime_only=runtime_only)
    return {target for target in found if target in ALL and target != name}


def layer(name: str) -> int | None:
    for rank, prefix in enumerate(GCS_LAYERS):
        if name == prefix or name.startswith(prefix + "."):
            return rank
    return None


def test_every_gcs_module_is_in_a_layer() -> None:
    stray = [m for m in modules("gcs") if m != "gcs" and layer(m) is None]
    assert not stray


@pytest.mark.parametrize("name", sorted(modules("gcs")))
def test_a_gcs_layer_imports_only_the_layers_below(name: str) -> None:
    own = layer(name)
    upward = sorted(
        target
        for target in project_imports(name)
        if target.startswith("gcs.") and own is not None and (layer(target) or 0) > own
    )
    assert not upward, f"{name} (layer {GCS_LAYERS[own or 0]}) imports higher layers: {upward}"


@pytest.mark.parametrize(
    ("package", "forbidden"),
    [("planner", ("gcs", "sitl_mock")), ("sitl_mock", ("gcs", "planner"))],
)
def test_planner_and_the_vehicles_stand_alone(package: str, forbidden: tuple[str, ...]) -> None:
    bad = {
        (name, target)
        for name in modules(package)
        for target in project_imports(name)
        if target.split(".")[0] in forbidden
    }
    assert not bad


def test_only_the_command_line_starts_simulated_vehicles() -> None:
    users = {
        name
        for name in modules("gcs")
        if any(t.startswith("sitl_mock") for t in project_imports(name))
    }
    assert users and all(layer(name) == GCS_LAYERS.index("gcs.cli") for name in users)


def test_no_import_cycles() -> None:
    """At run time (an import only for type checking cannot loop)."""
    graph = {name: project_imports(name, runtime_only=True) for name in ALL}
    done: set[str] = set()

    def visit(name: str, path: list[str]) -> None:
        if name in path:
            cycle = [*path[path.index(name) :], name]
            raise AssertionError(f"import cycle: {' -> '.join(cycle)}")
        if name in done:
            return
        for target in sorted(graph[name]):
            # a package's __init__ importing its own modules is not a cycle of theirs
            if not target.startswith(name + "."):
                visit(target, [*path, name])
        done.add(name)

    for name in sorted(graph):
        visit(name, [])


def test_the_rules_catch_an_upward_import(tmp_path: Path) -> None:
    """The checker itself: a mavlink module importing the fleet is reported."""
    module = tmp_path / "link.py"
    module.write_text("from gcs.fleet.fleet import Fleet\nimport gcs.service.settings\n")
    found = set(imports("gcs.mavlink.link", module))
    assert {"gcs.fleet.fleet", "gcs.service.settings"} <= found
    assert max(layer(t) or 0 for t in found) > layer("gcs.mavlink.link")  # type: ignore[operator]

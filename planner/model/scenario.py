"""The scenario a user asks us to plan: a grid, its UAVs, obstacles and non-UAV objects.

Geometry is in grid cells: x is the column, y the row, and cell (x, y) is the unit
square centred on the integer point (x, y). Time is in seconds from a common start.
"""

from __future__ import annotations

import os
from typing import Annotated, Any, Self

import numpy as np
from numpy.typing import NDArray
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)
from scipy import ndimage

MAX_GRID_SIDE = 500
"""Largest width or height accepted, in cells."""
MAX_UAVS = 250
"""Most UAVs in one scenario that may be flown: one MAVLink network (system ids 1-254,
the ground station's own 255 aside), with room to spare."""
PLANNED_UAVS_CEILING = 1000
"""Most UAVs any setting lets a planning-only scenario have (`max_planned_uavs`)."""
PLANNED_UAVS_ENV = "MVO_GCS_MAX_PLANNED_UAVS"
"""The setting: most UAVs in a scenario that is only planned (`mvo-gcs plan`), from
MAX_UAVS (the default) up to PLANNED_UAVS_CEILING."""
MAX_RANDOM_OBJECTS = 10_000

Cell = tuple[Annotated[int, Field(strict=True)], Annotated[int, Field(strict=True)]]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_booleans(cls, value: object) -> object:
        """JSON `true` is not a number here, though pydantic would read it as 1."""
        if isinstance(value, bool):
            raise ValueError("expected a number, not a boolean")
        return value


class Grid(_Strict):
    width: int = Field(strict=True, ge=1, le=MAX_GRID_SIDE, description="columns (x)")
    height: int = Field(strict=True, ge=1, le=MAX_GRID_SIDE, description="rows (y)")
    cell_size_m: float = Field(default=10.0, gt=0, le=10_000, description="metres per cell")

    def contains(self, cell: Cell) -> bool:
        return 0 <= cell[0] < self.width and 0 <= cell[1] < self.height


class Origin(_Strict):
    """Geographic position of cell (0, 0); only needed to fly the plan."""

    lat: float = Field(ge=-90, le=90)
    lon: float = Field(ge=-180, le=180)
    alt_m: float = Field(
        default=0.0, ge=-500, le=9_000, description="ground altitude, metres above MSL"
    )


MAX_RADIUS = 0.49
"""The largest radius a clearance grows a UAV to (cells): below half a cell."""


class UAVSpec(_Strict):
    id: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.:-]+$")
    start: Cell
    goal: Cell
    speed: float = Field(default=1.0, gt=0, le=1_000, description="cells per second")
    radius: float = Field(
        default=0.3,
        gt=0,
        lt=0.5,
        description="R in cells; below half a cell so that a UAV fits inside its cell",
    )

    @field_validator("speed", "radius", mode="before")
    @classmethod
    def _no_strings(cls, value: object) -> object:
        """JSON `"1"` is not a number here, though pydantic would read it as 1.0."""
        if isinstance(value, str):
            raise ValueError("expected a number, not a string")
        return value


class RandomObjects(_Strict):
    """`{"random": K, "seed": S}`: K non-UAV objects placed on free cells, as the paper does."""

    random: int = Field(strict=True, ge=0, le=MAX_RANDOM_OBJECTS)
    seed: int = Field(default=0, strict=True, ge=0, le=2**32 - 1)


class Scenario(_Strict):
    name: str = Field(default="scenario", max_length=200)
    grid: Grid
    origin: Origin | None = None
    uavs: list[UAVSpec] = Field(min_length=1, max_length=PLANNED_UAVS_CEILING)
    obstacles: list[Cell] = Field(default_factory=list)
    non_uav_objects: list[Cell] | RandomObjects = Field(default_factory=list)

    @model_validator(mode="after")
    def _check_layout(self, info: ValidationInfo) -> Self:
        limit = MAX_UAVS
        if isinstance(info.context, dict) and info.context.get("max_uavs") is not None:
            limit = int(info.context["max_uavs"])
        if len(self.uavs) > limit:
            raise ValueError(
                f"{len(self.uavs)} UAVs: at most {limit} per scenario"
                + (
                    f" (planning only: set {PLANNED_UAVS_ENV}, up to {PLANNED_UAVS_CEILING})"
                    if limit < PLANNED_UAVS_CEILING
                    else ""
                )
            )
        problems = _layout_problems(self)
        if problems:
            raise ValueError("; ".join(problems))
        return self

    def with_clearance(self, metres: float) -> Scenario:
        """The scenario with every UAV's radius grown by half of `metres`: a plan of it
        keeps every pair `metres` further apart than 2R (and each UAV further from the
        obstacles), room for real vehicles straying off their paths. A radius stays below
        half a cell (a UAV must fit in its cell): the clearance shrinks where it cannot."""
        grow = metres / 2 / self.grid.cell_size_m
        uavs = [
            u.model_copy(update={"radius": min(u.radius + grow, MAX_RADIUS)}) for u in self.uavs
        ]
        return self.model_copy(update={"uavs": uavs})

    def blocked(self) -> NDArray[np.bool_]:
        """Obstacle map indexed [x, y]."""
        grid = np.zeros((self.grid.width, self.grid.height), dtype=bool)
        if self.obstacles:
            xs, ys = np.array(self.obstacles).T
            grid[xs, ys] = True
        return grid

    def object_cells(self) -> list[Cell]:
        """The non-UAV objects' cells, drawing the random ones on free cells."""
        if isinstance(self.non_uav_objects, list):
            return list(self.non_uav_objects)
        free = ~self.blocked()
        for uav in self.uavs:
            free[uav.start] = free[uav.goal] = False
        cells = np.argwhere(free)
        count = min(self.non_uav_objects.random, len(cells))
        chosen = np.random.default_rng(self.non_uav_objects.seed).choice(
            len(cells), count, replace=False
        )
        return [(int(x), int(y)) for x, y in cells[np.sort(chosen)]]


def _layout_problems(s: Scenario) -> list[str]:
    """Everything that makes the scenario unplannable, as messages naming the field."""
    problems: list[str] = []
    size = f"{s.grid.width}x{s.grid.height} grid"
    cells = [
        (f"uavs[{i}].{end}", getattr(u, end))
        for i, u in enumerate(s.uavs)
        for end in ("start", "goal")
    ]
    cells += [(f"obstacles[{i}]", c) for i, c in enumerate(s.obstacles)]
    if isinstance(s.non_uav_objects, list):
        cells += [(f"non_uav_objects[{i}]", c) for i, c in enumerate(s.non_uav_objects)]
    problems += [
        f"{where} {cell} is outside the {size}"
        for where, cell in cells
        if not s.grid.contains(cell)
    ]
    if problems:
        return problems

    blocked = set(s.obstacles)
    objects = set(s.non_uav_objects) if isinstance(s.non_uav_objects, list) else set()
    for i, u in enumerate(s.uavs):
        for end in ("start", "goal"):
            cell = getattr(u, end)
            if cell in blocked:
                problems.append(f"uavs[{i}].{end} {cell} of {u.id!r} is on an obstacle")
            if cell in objects:
                problems.append(f"uavs[{i}].{end} {cell} of {u.id!r} is on a non-UAV object")

    seen: dict[str, int] = {}
    for i, u in enumerate(s.uavs):
        if u.id in seen:
            problems.append(f"uavs[{i}].id {u.id!r} repeats uavs[{seen[u.id]}].id")
        seen.setdefault(u.id, i)

    starts = np.array([u.start for u in s.uavs], dtype=float)
    radii = np.array([u.radius for u in s.uavs])
    gap = np.linalg.norm(starts[:, None] - starts[None, :], axis=2) - radii[:, None] - radii
    for i, j in zip(*np.nonzero(np.triu(gap < 0, k=1)), strict=True):
        problems.append(
            f"uavs[{i}] {s.uavs[i].id!r} and uavs[{j}] {s.uavs[j].id!r} start closer than "
            "the sum of their radii"
        )
    if problems:
        return problems
    return _unreachable_goals(s)


def _unreachable_goals(s: Scenario) -> list[str]:
    """Goals no path reaches even with the UAV alone on the grid.

    Diagonal moves may not cut the corner of a blocked cell, so a diagonal step is
    allowed only where both orthogonal neighbours are free: 8-connected moves then
    reach exactly the cells that 4-connected moves reach.
    """
    labels, _ = ndimage.label(~s.blocked())  # the default structure is 4-connectivity
    return [
        f"uavs[{i}].goal {u.goal} of {u.id!r} cannot be reached from its start {u.start}: "
        "obstacles wall it off"
        for i, u in enumerate(s.uavs)
        if labels[u.start] != labels[u.goal]
    ]


def max_planned_uavs() -> int:
    """Most UAVs in a scenario that is only planned: the PLANNED_UAVS_ENV setting (at
    least MAX_UAVS, at most PLANNED_UAVS_CEILING), MAX_UAVS when unset."""
    raw = os.environ.get(PLANNED_UAVS_ENV, "").strip()
    if not raw:
        return MAX_UAVS
    try:
        value = int(raw)
    except ValueError:
        raise ValueError(f"{PLANNED_UAVS_ENV}={raw!r} is not a whole number") from None
    return min(max(value, MAX_UAVS), PLANNED_UAVS_CEILING)


def load_scenario(data: dict[str, Any] | str | bytes, max_uavs: int | None = None) -> Scenario:
    """A validated scenario from a dict or JSON text (pydantic.ValidationError if invalid);
    at most `max_uavs` UAVs (default MAX_UAVS, the most that may be flown; more only for
    planning, at most PLANNED_UAVS_CEILING)."""
    context = {"max_uavs": min(max_uavs, PLANNED_UAVS_CEILING) if max_uavs else None}
    if isinstance(data, str | bytes):
        return Scenario.model_validate_json(data, context=context)
    return Scenario.model_validate(data, context=context)

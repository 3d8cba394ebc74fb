"""A complete search for the whole fleet at once: LaCAM over PIBT on the 4-connected grid.

The safe start (prioritized: one UAV made safe against the others held fixed) is fast
but incomplete: in a maze or a crowded room a UAV can be walled in by flights already
fixed, and no order of the UAVs helps. LaCAM (Okumura, "LaCAM: Search-Based Algorithm
for Quick Multi-Agent Pathfinding", AAAI 2023) searches configurations of the whole fleet
instead, one time step at a time, and is complete: it finds a solution or proves there
is none, given the nodes.

- **Steps.** Every UAV either stays or moves to a 4-connected free neighbour in each step;
  no two end a step in one cell, and no two swap cells. A UAV vanishes the step after it
  first reaches its goal: in our model a flight ends at its goal (it lands), and
  vanishing there never hinders anyone, so a solution that does so exists whenever one
  exists at all.
- **Successors (PIBT).** Priority inheritance with backtracking (Okumura et al., AIJ
  2022) moves each UAV to the free neighbour nearest its goal, in priority order; a
  UAV in the way is asked to move first, and a request it cannot meet is withdrawn.
- **The search (LaCAM).** A depth-first search over configurations. Each one keeps a
  tree of constraints ("UAV i goes to cell v next"), grown one UAV deeper each time the
  configuration is revisited, and PIBT fills in the UAVs left free. So every successor
  of every configuration is reached in the end: that is what makes it complete.

`planner.flows.complete_start` turns the steps into flights and says when they are safe
in continuous time (the radii and speeds it needs).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

Cell = tuple[int, int]
GONE = -1  # a UAV that has reached its goal and left
UNSET = -2  # a UAV whose next cell is not chosen yet
MOVES = ((1, 0), (-1, 0), (0, 1), (0, -1))
Outcome = Literal["solved", "no solution", "node limit", "time limit"]


@dataclass(frozen=True)
class Result:
    """What the search found: every step's cell of every UAV (None once it has left) if
    `outcome` is "solved", and how many configurations it made."""

    outcome: Outcome
    steps: list[list[Cell | None]]
    nodes: int


@dataclass
class _Constraint:
    """A node of a configuration's constraint tree: `who[k]` goes to `where[k]` next."""

    who: tuple[int, ...] = ()
    where: tuple[int, ...] = ()

    def child(self, uav: int, cell: int) -> _Constraint:
        return _Constraint((*self.who, uav), (*self.where, cell))


@dataclass
class _Node:
    config: NDArray[np.int32]  # each UAV's cell (flat index into the free cells) or GONE
    parent: _Node | None
    priority: NDArray[np.float64]
    order: list[int]  # the UAVs still to move, highest priority first
    tree: deque[_Constraint] = field(default_factory=lambda: deque([_Constraint()]))


class _Grid:
    """The free cells, their 4-connected neighbours and every UAV's distance to its goal."""

    def __init__(self, free: NDArray[np.bool_], goals: Sequence[Cell]) -> None:
        width, height = free.shape
        index = np.full(free.shape, -1, dtype=np.int64)
        xs, ys = np.nonzero(free)
        index[xs, ys] = np.arange(len(xs))
        self.index, self.cells = index, list(zip(xs.tolist(), ys.tolist(), strict=True))
        rows, cols = [], []
        for dx, dy in MOVES:
            nx, ny = xs + dx, ys + dy
            inside = (nx >= 0) & (nx < width) & (ny >= 0) & (ny < height)
            ok = np.zeros(len(xs), dtype=bool)
            ok[inside] = free[nx[inside], ny[inside]]
            rows.append(index[xs[ok], ys[ok]])
            cols.append(index[nx[ok], ny[ok]])
        row, col = np.concatenate(rows), np.concatenate(cols)
        size = len(xs)
        graph = coo_matrix((np.ones(len(row)), (row, col)), shape=(size, size)).tocsr()
        self.neighbours: list[list[int]] = [[] for _ in range(size)]
        for a, b in zip(row.tolist(), col.tolist(), strict=True):
            self.neighbours[a].append(b)
        self.goals = [int(index[g]) for g in goals]
        self.goal_array = np.array(self.goals, dtype=np.int32)
        self.distance = np.empty((len(goals), size), dtype=np.int32)
        for i, goal in enumerate(self.goals):  # one at a time: int32 rows, not float64 ones
            row = dijkstra(graph, unweighted=True, indices=goal)
            self.distance[i] = np.where(np.isinf(row), size, row)  # cut off: beyond all


def search(
    free: NDArray[np.bool_],
    starts: Sequence[Cell],
    goals: Sequence[Cell],
    rng: np.random.Generator,
    max_nodes: int = 200_000,
    expired: Callable[[], bool] = lambda: False,
) -> Result:
    """Steps from `starts` to `goals` on the free cells of `free` (indexed [x, y]) in which
    no two UAVs share a cell or swap, each UAV leaving at its goal; `rng` breaks ties.
    Starts must be distinct free cells, and so must goals."""
    grid = _Grid(free, goals)
    n = len(starts)
    start = np.array([grid.index[s] for s in starts], dtype=np.int32)
    if any(grid.distance[i, start[i]] >= len(grid.cells) for i in range(n)):
        return Result("no solution", [], 0)
    pibt = _Pibt(grid, rng)
    first = _node(grid, start, None, np.zeros(n))
    stack, seen = [first], {first.config.tobytes()}
    nodes = 1
    while stack:
        if nodes >= max_nodes:
            return Result("node limit", [], nodes)
        if nodes % 64 == 0 and expired():
            return Result("time limit", [], nodes)
        node = stack[-1]
        if not node.order:  # every UAV on its goal or gone
            return Result("solved", without_loops(_steps(grid, node)), nodes)
        if not node.tree:
            stack.pop()
            continue
        constraint = node.tree.popleft()
        _grow(grid, node, constraint, rng)
        following = pibt.successor(node, constraint)
        if following is None:
            continue
        key = following.tobytes()
        if key in seen:
            continue
        seen.add(key)
        stack.append(_node(grid, following, node, node.priority))
        nodes += 1
    return Result("no solution", [], nodes)


def _node(
    grid: _Grid, config: NDArray[np.int32], parent: _Node | None, priority: NDArray[np.float64]
) -> _Node:
    """A configuration, its UAVs' priorities (one more for each step a UAV is away from its
    goal; the fraction of its first distance breaks ties) and the order of those still to
    move (a UAV on its goal leaves in the next step)."""
    n = len(config)
    active = np.flatnonzero((config != GONE) & (config != grid.goal_array))
    if parent is None:
        distance = grid.distance[np.arange(n), np.maximum(config, 0)]
        priority = distance / (distance.max(initial=0) + 1.0)
    priority = priority.copy()
    priority[active] += 1.0
    order = sorted(active.tolist(), key=lambda i: -priority[i])
    return _Node(config, parent, priority, order)


def _grow(grid: _Grid, node: _Node, constraint: _Constraint, rng: np.random.Generator) -> None:
    """The constraint's children: the next UAV in order at each cell it can reach."""
    depth = len(constraint.who)
    if depth >= len(node.order):
        return
    uav = node.order[depth]
    at = int(node.config[uav])
    options = [at, *grid.neighbours[at]]
    for k in rng.permutation(len(options)).tolist():
        node.tree.append(constraint.child(uav, options[k]))


class _Pibt:
    """Successor configurations by priority inheritance with backtracking."""

    def __init__(self, grid: _Grid, rng: np.random.Generator) -> None:
        self.grid, self.rng = grid, rng
        self.now = [-1] * len(grid.cells)  # who is in each cell
        self.next = [-1] * len(grid.cells)  # who goes to each cell
        self.config: list[int] = []
        self.following: list[int] = []
        self.ties: NDArray[np.float64] = np.zeros(0)

    def successor(self, node: _Node, constraint: _Constraint) -> NDArray[np.int32] | None:
        """The configuration after `node` that meets `constraint`, or None."""
        config = node.config.tolist()
        goals = self.grid.goals
        following = [GONE if c == GONE or c == goals[i] else UNSET for i, c in enumerate(config)]
        self.config, self.following = config, following
        moving = [i for i, c in enumerate(following) if c == UNSET]
        for i in moving:
            self.now[config[i]] = i
        self.ties = self.rng.random((len(config), 5))
        try:
            if self._constrain(constraint) and all(
                following[i] != UNSET or self._move(i) for i in node.order
            ):
                return np.array(following, dtype=np.int32)
            return None
        finally:
            for i in moving:
                self.now[config[i]] = -1
                if following[i] >= 0:
                    self.next[following[i]] = -1

    def _constrain(self, constraint: _Constraint) -> bool:
        config, following = self.config, self.following
        for uav, cell in zip(constraint.who, constraint.where, strict=True):
            if cell == GONE:
                continue
            other = self.now[cell]
            if self.next[cell] != -1 or (
                other not in (-1, uav) and following[other] == config[uav]
            ):
                return False
            following[uav], self.next[cell] = cell, uav
        return True

    def _move(self, i: int) -> bool:
        """PIBT's step for UAV i: the free cell nearest its goal; a UAV in the way moves
        first (it inherits i's priority) or i tries its next choice."""
        config, following, grid = self.config, self.following, self.grid
        at = config[i]
        distance, ties = grid.distance[i], self.ties[i]
        options = sorted(
            (distance[c], ties[k], c) for k, c in enumerate([at, *grid.neighbours[at]])
        )
        for _, _, cell in options:
            if self.next[cell] != -1:
                continue
            other = self.now[cell]
            if other not in (-1, i) and following[other] == at:
                continue  # a swap
            following[i], self.next[cell] = cell, i
            if other in (-1, i) or following[other] != UNSET or self._move(other):
                return True
        following[i] = at
        self.next[at] = i
        return False


def _steps(grid: _Grid, last: _Node) -> list[list[Cell | None]]:
    """The configurations from the first to `last`, then the step in which all leave."""
    configs = []
    node: _Node | None = last
    while node is not None:
        configs.append(node.config)
        node = node.parent
    configs.reverse()
    configs.append(np.full(len(last.config), GONE, dtype=np.int32))
    return [[None if c == GONE else grid.cells[c] for c in config.tolist()] for config in configs]


def without_loops(steps: list[list[Cell | None]]) -> list[list[Cell | None]]:
    """`steps` with each UAV's loops cut out: where it comes back to a cell it was in, it
    waits there instead, if nobody else enters that cell meanwhile (PIBT's plans wander
    to and fro while others pass). Arrival times stay as they were; a UAV waiting in a
    cell nobody enters conflicts with nobody, so the steps stay valid."""
    rows = [list(row) for row in steps]
    occupant: dict[tuple[int, Cell], int] = {}
    for t, row in enumerate(rows):
        for uav, cell in enumerate(row):
            if cell is not None:
                occupant[t, cell] = uav
    for uav in range(len(rows[0]) if rows else 0):
        t = 0
        while t < len(rows) and (cell := rows[t][uav]) is not None:
            back = _last_return(rows, occupant, uav, t, cell)
            for s in range(t + 1, back):
                was = rows[s][uav]
                if was is not None:
                    del occupant[s, was]
                rows[s][uav] = cell
                occupant[s, cell] = uav
            t = max(back, t + 1)
    return rows


def _last_return(
    rows: list[list[Cell | None]],
    occupant: dict[tuple[int, Cell], int],
    uav: int,
    t: int,
    cell: Cell,
) -> int:
    """The last step at which `uav` is back in `cell`, its cell of step `t`, with that
    cell free of others in between (t if none)."""
    best = t
    for s in range(t + 1, len(rows)):
        if occupant.get((s, cell), uav) != uav:
            break  # someone else is there: no wait at `cell` can reach past this
        if rows[s][uav] == cell:
            best = s
    return best

import itertools
import math

import numpy as np

from planner.geometry.grid_search import GridGraph, path_length


def test_straight_and_diagonal_costs() -> None:
    graph = GridGraph.build(np.zeros((6, 6), dtype=bool))
    path = graph.shortest_path((0, 0), (5, 3))
    assert path is not None
    assert path[0] == (0, 0) and path[-1] == (5, 3)
    assert math.isclose(path_length(path), 2 + 3 * math.sqrt(2))
    assert all(max(abs(a - c), abs(b - d)) == 1 for (a, b), (c, d) in itertools.pairwise(path))


def test_no_corner_cutting_around_a_blocked_cell() -> None:
    blocked = np.zeros((3, 3), dtype=bool)
    blocked[1, 0] = True
    graph = GridGraph.build(blocked)
    # Both diagonals past (1, 0) would cut its corner: around it takes four straight steps.
    path = graph.shortest_path((0, 0), (2, 0))
    assert path is not None and path_length(path) == 4.0
    d = graph.distances_to((1, 1))
    assert math.isclose(d[0, 0], 2.0)  # not sqrt(2): the diagonal is forbidden


def test_unreachable_goal() -> None:
    blocked = np.zeros((4, 1), dtype=bool)
    blocked[2, 0] = True
    assert GridGraph.build(blocked).shortest_path((0, 0), (3, 0)) is None

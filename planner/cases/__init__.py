"""The six cases of the paper's Fig. 2 and Table III, rebuilt as small grids (see README.md)."""

from __future__ import annotations

from importlib.resources import files
from typing import Any

from planner.model.scenario import Scenario, load_scenario

CASES = tuple(f"case-{k}" for k in range(1, 7))

# Table III of the paper: Dist(t0), #UAVs as printed, mean deviation, and J for
# populations 10, 15, 20 and 30.
PAPER_TABLE_III: dict[str, dict[str, Any]] = {
    "case-1": {"dist": 4.0, "uavs": 2, "deviation": 0.5, "J": (2.0178, 2.1237, 1.9371, 1.9023)},
    "case-2": {"dist": 3.0, "uavs": 3, "deviation": 0.5, "J": (8.8745, 8.7241, 8.2412, 8.0918)},
    "case-3": {
        "dist": 2.83,
        "uavs": 3,
        "deviation": 1.0,
        "J": (11.3137, 11.9209, 11.2324, 11.1265),
    },
    "case-4": {"dist": 4.65, "uavs": 2, "deviation": 1.5, "J": (3.3715, 3.0115, 2.9213, 2.8016)},
    "case-5": {
        "dist": 2.15,
        "uavs": 3,
        "deviation": 0.67,
        "J": (12.4009, 12.4116, 12.2020, 12.1012),
    },
    "case-6": {"dist": 4.0, "uavs": 3, "deviation": 1.0, "J": (9.3567, 9.1216, 8.9817, 8.1815)},
}
PAPER_POPULATIONS = (10, 15, 20, 30)


def load_case(name: str) -> Scenario:
    """One of `CASES`, e.g. "case-6"."""
    if name not in CASES:
        raise KeyError(f"unknown case {name!r}; the paper's cases are {', '.join(CASES)}")
    return load_scenario(files(__package__).joinpath(f"{name}.json").read_text())

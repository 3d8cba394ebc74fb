import json

import pytest
from pydantic import ValidationError

from planner.model.scenario import MAX_GRID_SIDE, Scenario, load_scenario


def scenario(**changes) -> dict:
    base = {
        "name": "t",
        "grid": {"width": 10, "height": 8, "cell_size_m": 5.0},
        "uavs": [
            {"id": "a", "start": [0, 0], "goal": [9, 7], "speed": 1.0, "radius": 0.3},
            {"id": "b", "start": [9, 0], "goal": [0, 7]},
        ],
        "obstacles": [[4, 4]],
        "non_uav_objects": [[6, 2]],
    }
    base.update(changes)
    return base


def error_text(data: dict) -> str:
    with pytest.raises(ValidationError) as info:
        load_scenario(data)
    return str(info.value)


def test_valid_scenario_round_trips_through_json() -> None:
    s = load_scenario(json.dumps(scenario()))
    assert s.uavs[1].radius == 0.3 and s.uavs[1].speed == 1.0  # defaults
    assert load_scenario(s.model_dump_json()) == s
    assert s.blocked()[4, 4] and s.blocked().sum() == 1


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"uavs": [{"id": "a", "start": [0, 0], "goal": [10, 7]}]},
            "uavs[0].goal (10, 7) is outside the 10x8 grid",
        ),
        ({"obstacles": [[0, 0]]}, "uavs[0].start (0, 0) of 'a' is on an obstacle"),
        ({"non_uav_objects": [[9, 7]]}, "uavs[0].goal (9, 7) of 'a' is on a non-UAV object"),
        (
            {
                "uavs": [
                    {"id": "a", "start": [0, 0], "goal": [1, 1]},
                    {"id": "a", "start": [5, 5], "goal": [2, 2]},
                ]
            },
            "uavs[1].id 'a' repeats uavs[0].id",
        ),
        (
            {
                "uavs": [
                    {"id": "a", "start": [0, 0], "goal": [1, 1], "radius": 0.45},
                    {"id": "b", "start": [0, 0], "goal": [2, 2]},
                ]
            },
            "start closer than the sum of their radii",
        ),
        (
            {"obstacles": [[8, 7], [8, 6], [9, 6]]},
            "uavs[0].goal (9, 7) of 'a' cannot be reached from its start (0, 0)",
        ),
        ({"uavs": [{"id": "a", "start": [0, 0], "goal": [1, 1], "speed": 0}]}, "greater than 0"),
        ({"uavs": [{"id": "a", "start": [0, 0], "goal": [1, 1], "radius": 0.5}]}, "less than 0.5"),
        ({"uavs": []}, "at least 1 item"),
        ({"surprise": True}, "Extra inputs are not permitted"),
        (
            {"grid": {"width": MAX_GRID_SIDE + 1, "height": 5}},
            f"less than or equal to {MAX_GRID_SIDE}",
        ),
        ({"uavs": [{"id": "a", "start": [0.5, 0], "goal": [1, 1]}]}, "valid integer"),
    ],
)
def test_invalid_scenarios_say_what_and_where(changes: dict, message: str) -> None:
    assert message in error_text(scenario(**changes))


def test_diagonal_gaps_do_not_connect_walled_goals() -> None:
    # (1, 1) is reachable only by cutting between (0, 1) and (1, 0): not allowed.
    data = scenario(
        grid={"width": 3, "height": 3},
        uavs=[{"id": "a", "start": [0, 0], "goal": [2, 2]}],
        obstacles=[[0, 1], [1, 0]],
        non_uav_objects=[],
    )
    assert "cannot be reached" in error_text(data)


def test_documented_size_limits_are_accepted() -> None:
    uavs = [{"id": f"u{i}", "start": [i * 2, 0], "goal": [i * 2, 199]} for i in range(50)]
    s = load_scenario({"grid": {"width": 200, "height": 200}, "uavs": uavs})
    assert len(s.uavs) == 50


def test_random_objects_land_on_free_cells_reproducibly() -> None:
    data = scenario(non_uav_objects={"random": 12, "seed": 7})
    first, again = load_scenario(data).object_cells(), load_scenario(data).object_cells()
    assert first == again and len(set(first)) == 12
    s: Scenario = load_scenario(data)
    taken = {tuple(u.start) for u in s.uavs} | {tuple(u.goal) for u in s.uavs} | {(4, 4)}
    assert not taken & set(first)
    other = load_scenario(scenario(non_uav_objects={"random": 12, "seed": 8})).object_cells()
    assert other != first


def _fleet_of(count: int) -> dict:
    uavs = [
        {"id": f"u{k}", "start": [k % 300, k // 300], "goal": [k % 300, 499]} for k in range(count)
    ]
    return scenario(grid={"width": 300, "height": 500}, uavs=uavs, obstacles=[], non_uav_objects=[])


def test_a_scenario_takes_a_mavlink_network_of_uavs_and_more_only_for_planning(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from planner.model.scenario import (
        MAX_UAVS,
        PLANNED_UAVS_CEILING,
        PLANNED_UAVS_ENV,
        max_planned_uavs,
    )

    assert MAX_UAVS == 250
    assert len(load_scenario(_fleet_of(250)).uavs) == 250
    assert f"251 UAVs: at most 250 per scenario (planning only: set {PLANNED_UAVS_ENV}" in (
        error_text(_fleet_of(251))
    )
    assert len(load_scenario(_fleet_of(400), max_uavs=400).uavs) == 400
    monkeypatch.delenv(PLANNED_UAVS_ENV, raising=False)
    assert max_planned_uavs() == MAX_UAVS
    monkeypatch.setenv(PLANNED_UAVS_ENV, "400")
    assert max_planned_uavs() == 400
    monkeypatch.setenv(PLANNED_UAVS_ENV, "100000")
    assert max_planned_uavs() == PLANNED_UAVS_CEILING
    with pytest.raises(ValidationError):
        load_scenario(_fleet_of(PLANNED_UAVS_CEILING + 1), max_uavs=PLANNED_UAVS_CEILING + 5)

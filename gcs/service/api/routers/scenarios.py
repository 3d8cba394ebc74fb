"""Scenarios: the planner's scenario JSON, stored under an id."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Query, status

from gcs.service.api.deps import ServicesDep, mutating
from gcs.service.api.schemas import Problem, ScenarioOut
from gcs.service.storage.tables import ScenarioRow
from planner.scenario import Scenario

router = APIRouter(prefix="/scenarios", tags=["scenarios"])
NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {"model": Problem, "description": "no such scenario"}
}


def _out(row: ScenarioRow) -> ScenarioOut:
    return ScenarioOut(
        id=row.id, name=row.name, created_at=row.created_at, scenario=Scenario(**row.body)
    )


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    **mutating(),
)
def create_scenario(scenario: Scenario, services: ServicesDep) -> ScenarioOut:
    """Store a scenario (validated: grid limits, cells inside the grid, reachable goals)."""
    row = ScenarioRow(name=scenario.name, body=scenario.model_dump(mode="json"))
    return _out(services.scenarios.add(row))


@router.get("")
def list_scenarios(
    services: ServicesDep,
    limit: int = Query(default=100, ge=1, le=1000),
    offset: int = Query(default=0, ge=0, le=10**9),
) -> list[ScenarioOut]:
    return [_out(row) for row in services.scenarios.list(limit, offset)]


@router.get("/{scenario_id}", responses=NOT_FOUND)
def get_scenario(scenario_id: str, services: ServicesDep) -> ScenarioOut:
    return _out(services.scenarios.get(scenario_id))


@router.delete(
    "/{scenario_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    **mutating(NOT_FOUND),
)
def delete_scenario(scenario_id: str, services: ServicesDep) -> None:
    """Delete a scenario with its plans and jobs."""
    services.scenarios.delete(scenario_id)

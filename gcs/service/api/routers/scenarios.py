"""Scenarios: the planner's scenario JSON, stored under an id."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Query, status

from gcs.service.api.deps import (
    FlightsDep,
    MissionFilesDep,
    PlanningDep,
    PlansDep,
    ScenariosDep,
    mutating,
)
from gcs.service.api.schemas import MAX_PAGE, Problem, ScenarioOut, ScenarioSummary
from gcs.service.states import OPEN, StateConflict
from gcs.service.storage.tables import ScenarioRow
from planner.scenario import Scenario

router = APIRouter(prefix="/scenarios", tags=["scenarios"])
NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {"model": Problem, "description": "no such scenario"}
}
SCENARIO_LINKS = {
    op: {"operationId": op, "parameters": {"scenario_id": "$response.body#/id"}}
    for op in ("getScenario", "requestPlan", "listPlans", "deleteScenario")
}


def _out(row: ScenarioRow) -> ScenarioOut:
    return ScenarioOut(
        id=row.id, name=row.name, created_at=row.created_at, scenario=Scenario(**row.body)
    )


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    operation_id="createScenario",
    **mutating({201: {"links": SCENARIO_LINKS}}),
)
async def create_scenario(scenario: Scenario, scenarios: ScenariosDep) -> ScenarioOut:
    """Store a scenario (validated: grid limits, cells inside the grid, reachable goals)."""
    row = ScenarioRow(name=scenario.name, body=scenario.model_dump(mode="json"))
    return _out(await scenarios.add(row))


@router.get("", operation_id="listScenarios")
async def list_scenarios(
    scenarios: ScenariosDep,
    limit: int = Query(default=50, ge=1, le=MAX_PAGE),
    offset: int = Query(default=0, ge=0, le=10**9),
) -> list[ScenarioSummary]:
    """Oldest first, summarised (a page of whole scenarios could be megabytes)."""
    return [_summary(row) for row in await scenarios.page(limit, offset)]


def _summary(row: ScenarioRow) -> ScenarioSummary:
    grid = row.body.get("grid", {})
    return ScenarioSummary(
        id=row.id,
        name=row.name,
        created_at=row.created_at,
        grid=[grid.get("width", 0), grid.get("height", 0)],
        uavs=len(row.body.get("uavs", [])),
    )


@router.get("/{scenario_id}", operation_id="getScenario", responses=NOT_FOUND)
async def get_scenario(scenario_id: str, scenarios: ScenariosDep) -> ScenarioOut:
    return _out(await scenarios.get(scenario_id))


@router.delete(
    "/{scenario_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    operation_id="deleteScenario",
    **mutating(
        {**NOT_FOUND, 409: {"model": Problem, "description": "an open flight flies its plan"}}
    ),
)
async def delete_scenario(
    scenario_id: str,
    scenarios: ScenariosDep,
    plans: PlansDep,
    planning: PlanningDep,
    flights: FlightsDep,
    mission_files: MissionFilesDep,
) -> None:
    """Delete a scenario with its plans, jobs and ended flights. Refused while an open
    flight flies one of its plans; planning jobs still running are cancelled first."""
    await scenarios.get(scenario_id)
    await planning.cancel_for_scenario(scenario_id)
    async with flights.book.claims:  # no upload may claim one of its plans meanwhile
        plan_ids = await plans.ids_for_scenario(scenario_id)
        flying = [f for f in await flights.book.flights.for_plans(plan_ids) if f.state in OPEN]
        if flying:
            raise StateConflict(
                f"scenario {scenario_id}: flight {flying[0].id} ({flying[0].state}) "
                "flies one of its plans; abort or end it first"
            )
        await scenarios.delete(scenario_id)
    mission_files.forget(*plan_ids, scenario_id=scenario_id)

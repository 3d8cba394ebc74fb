"""The paper's six cases, ready to load into the console or POST as scenarios."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from pydantic import BaseModel

from gcs.service.api.schemas import Problem
from gcs.service.storage import NotFound
from planner.cases import CASES, load_case
from planner.model.scenario import Scenario

router = APIRouter(prefix="/cases", tags=["cases"])
NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": Problem}}


class CaseOut(BaseModel):
    name: str
    uavs: int
    objects: int
    grid: list[int]


@router.get("", operation_id="listCases")
async def list_cases() -> list[CaseOut]:
    out = []
    for name in CASES:
        case = load_case(name)
        grid = [case.grid.width, case.grid.height]
        objects = case.non_uav_objects
        count = len(objects) if isinstance(objects, list) else objects.random
        out.append(CaseOut(name=name, uavs=len(case.uavs), objects=count, grid=grid))
    return out


@router.get("/{name}", operation_id="getCase", responses=NOT_FOUND)
async def get_case(name: str) -> Scenario:
    if name not in CASES:
        raise NotFound("case", name)
    return load_case(name)

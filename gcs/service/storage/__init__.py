"""Persistence: SQLite by default, any SQLAlchemy URL (PostgreSQL) by setting."""

from gcs.service.storage.database import Database
from gcs.service.storage.repositories import (
    FlightRepository,
    JobRepository,
    NotFound,
    PlanRepository,
    ScenarioRepository,
    VehicleRepository,
)

__all__ = [
    "Database",
    "FlightRepository",
    "JobRepository",
    "NotFound",
    "PlanRepository",
    "ScenarioRepository",
    "VehicleRepository",
]

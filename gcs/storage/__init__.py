"""Persistence: SQLite by default, any SQLAlchemy URL (PostgreSQL) by setting."""

from gcs.storage.database import Database
from gcs.storage.repositories import (
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

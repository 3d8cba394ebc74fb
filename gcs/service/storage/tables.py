"""The stored records. JSON columns hold the pydantic models' own JSON, so the API and
the store agree on one schema. A change here needs a migration (migrations/versions/);
the tests check that the two agree."""

from __future__ import annotations

import uuid
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column


def new_id() -> str:
    return uuid.uuid4().hex[:12]


def now() -> datetime:
    return datetime.now(UTC)


class Base(DeclarativeBase):
    type_annotation_map = {dict[str, Any]: JSON, list[Any]: JSON}  # noqa: RUF012


class ScenarioRow(Base):
    __tablename__ = "scenarios"
    id: Mapped[str] = mapped_column(String(12), primary_key=True, default=new_id)
    name: Mapped[str] = mapped_column(String(200))
    body: Mapped[dict[str, Any]]
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=now)
    geographic: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    """The geographic scenario (GeoJSON) `body` was derived from, as it was sent."""


class PlanRow(Base):
    __tablename__ = "plans"
    id: Mapped[str] = mapped_column(String(12), primary_key=True, default=new_id)
    scenario_id: Mapped[str] = mapped_column(ForeignKey("scenarios.id", ondelete="CASCADE"))
    feasible: Mapped[bool]
    body: Mapped[dict[str, Any]]
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=now)
    candidates: Mapped[list[dict[str, Any]] | None] = mapped_column(JSON, nullable=True)
    """What each candidate came to when several were planned for the plan's job
    (`planning_pool.candidates_json`); None when the plan was planned alone."""


class JobRow(Base):
    __tablename__ = "jobs"
    id: Mapped[str] = mapped_column(String(12), primary_key=True, default=new_id)
    scenario_id: Mapped[str] = mapped_column(ForeignKey("scenarios.id", ondelete="CASCADE"))
    settings: Mapped[dict[str, Any]]
    state: Mapped[str] = mapped_column(String(16), default="queued")
    percent: Mapped[float] = mapped_column(Float, default=0.0)
    best_cost: Mapped[float | None] = mapped_column(Float, nullable=True)
    first_safe_s: Mapped[float | None] = mapped_column(Float, nullable=True)
    plan_id: Mapped[str | None] = mapped_column(String(12), nullable=True)
    error: Mapped[str | None] = mapped_column(Text, nullable=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=now)
    updated_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=now)
    owner_id: Mapped[str | None] = mapped_column(String(200), nullable=True)
    """The service that runs it (it made it); nobody else ever runs it."""
    lease_expires_at: Mapped[datetime | None] = mapped_column(
        DateTime(timezone=True), nullable=True
    )
    """Its owner renews this while it lives; once past, the owner is taken for dead."""


class VehicleRow(Base):
    __tablename__ = "vehicles"
    id: Mapped[str] = mapped_column(String(12), primary_key=True, default=new_id)
    name: Mapped[str] = mapped_column(String(100))
    connection: Mapped[str] = mapped_column(String(200))  # canonical (gcs.mavlink.endpoint)
    sysid: Mapped[int | None] = mapped_column(Integer, nullable=True)
    signing_key: Mapped[str | None] = mapped_column(Text, nullable=True)  # never shown
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=now)
    __table_args__ = (UniqueConstraint("connection", "sysid"),)


class FlightRow(Base):
    __tablename__ = "flights"
    id: Mapped[str] = mapped_column(String(12), primary_key=True, default=new_id)
    plan_id: Mapped[str] = mapped_column(ForeignKey("plans.id", ondelete="CASCADE"))
    bindings: Mapped[dict[str, Any]]  # uav id -> vehicle id
    options: Mapped[dict[str, Any]]  # altitude, finish, ...
    state: Mapped[str] = mapped_column(String(16), default="created")
    note: Mapped[str] = mapped_column(Text, default="", server_default="")  # why this state
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=now)
    updated_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    owner_id: Mapped[str | None] = mapped_column(String(200), nullable=True)
    """The service that controls it (from its upload on); one at a time."""
    owner_url: Mapped[str | None] = mapped_column(String(500), nullable=True)
    """Where that service answers (its advertised base URL), for the 409 of the others."""
    lease_expires_at: Mapped[datetime | None] = mapped_column(
        DateTime(timezone=True), nullable=True
    )
    """The owner renews this while it lives; once past, another service may take over."""


class UploadRow(Base):
    __tablename__ = "uploads"
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    flight_id: Mapped[str] = mapped_column(ForeignKey("flights.id", ondelete="CASCADE"))
    uav_id: Mapped[str] = mapped_column(String(64))
    vehicle_id: Mapped[str] = mapped_column(String(12))
    ok: Mapped[bool]
    items: Mapped[int]
    detail: Mapped[str] = mapped_column(Text, default="")
    mission: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)  # as sent
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=now)


class EventRow(Base):
    __tablename__ = "events"
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    flight_id: Mapped[str] = mapped_column(ForeignKey("flights.id", ondelete="CASCADE"))
    kind: Mapped[str] = mapped_column(String(40))
    uav_id: Mapped[str | None] = mapped_column(String(64), nullable=True)
    data: Mapped[dict[str, Any]]
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=now)
    __table_args__ = (Index("ix_events_flight_id_id", "flight_id", "id"),)  # a flight's page

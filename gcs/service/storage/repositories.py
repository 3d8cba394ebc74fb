"""One small repository per stored aggregate; each call is its own transaction."""

from __future__ import annotations

from typing import Any, TypeVar

from sqlalchemy import delete, select

from gcs.service.storage.database import Database, rowcount
from gcs.service.storage.tables import (
    Base,
    EventRow,
    FlightRow,
    JobRow,
    PlanRow,
    ScenarioRow,
    UploadRow,
    VehicleRow,
    now,
)

Row = TypeVar("Row", bound=Base)


class NotFound(LookupError):
    """An id that names nothing; the API answers 404 with this message."""

    def __init__(self, kind: str, id_: str) -> None:
        super().__init__(f"no {kind} with id {id_!r}")
        self.kind, self.id = kind, id_


class _Repository:
    row: Any  # the table class: a Base subclass with `id` and `created_at`
    kind: str

    def __init__(self, db: Database) -> None:
        self.db = db

    def get(self, id_: str) -> Any:
        with self.db.session() as s:
            found = s.get(self.row, id_)
            if found is None:
                raise NotFound(self.kind, id_)
            return found

    def list(self, limit: int = 100, offset: int = 0) -> list[Any]:
        with self.db.session() as s:
            query = select(self.row).order_by(self.row.created_at).limit(limit).offset(offset)
            return list(s.scalars(query))

    def add(self, row: Row) -> Row:
        with self.db.session() as s:
            s.add(row)
        return row

    def delete(self, id_: str) -> None:
        with self.db.session() as s:
            if rowcount(s.execute(delete(self.row).where(self.row.id == id_))) == 0:
                raise NotFound(self.kind, id_)

    def update(self, id_: str, **values: Any) -> Any:
        with self.db.session() as s:
            found = s.get(self.row, id_)
            if found is None:
                raise NotFound(self.kind, id_)
            for key, value in values.items():
                setattr(found, key, value)
            return found


class ScenarioRepository(_Repository):
    row, kind = ScenarioRow, "scenario"


class PlanRepository(_Repository):
    row, kind = PlanRow, "plan"

    def for_scenario(self, scenario_id: str) -> list[PlanRow]:
        with self.db.session() as s:
            query = select(PlanRow).where(PlanRow.scenario_id == scenario_id)
            return list(s.scalars(query.order_by(PlanRow.created_at)))


class JobRepository(_Repository):
    row, kind = JobRow, "job"

    def update(self, id_: str, **values: Any) -> JobRow:
        return super().update(id_, updated_at=now(), **values)


class VehicleRepository(_Repository):
    row, kind = VehicleRow, "vehicle"

    def by_connection(self, connection: str) -> VehicleRow | None:
        with self.db.session() as s:
            return s.scalars(select(VehicleRow).where(VehicleRow.connection == connection)).first()


class FlightRepository(_Repository):
    row, kind = FlightRow, "flight"

    def record_event(
        self, flight_id: str, kind: str, data: dict[str, Any], uav_id: str | None = None
    ) -> EventRow:
        return self.add(EventRow(flight_id=flight_id, kind=kind, uav_id=uav_id, data=data))

    def events(self, flight_id: str, after: int = 0, limit: int = 1000) -> list[EventRow]:
        with self.db.session() as s:
            query = (
                select(EventRow)
                .where(EventRow.flight_id == flight_id, EventRow.id > after)
                .order_by(EventRow.id)
                .limit(limit)
            )
            return list(s.scalars(query))

    def record_upload(self, row: UploadRow) -> UploadRow:
        return self.add(row)

    def uploads(self, flight_id: str) -> list[UploadRow]:
        with self.db.session() as s:
            query = select(UploadRow).where(UploadRow.flight_id == flight_id)
            return list(s.scalars(query.order_by(UploadRow.id)))

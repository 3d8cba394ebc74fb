"""One small repository per stored aggregate; each call is its own transaction, run on a
storage thread (`Database.run`), so every public method is a coroutine."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from sqlalchemy import delete, func, select, update

from gcs.service.states import (
    FLIGHT_TRANSITIONS,
    JOB_TRANSITIONS,
    OPEN,
    FlightState,
    JobState,
    StateConflict,
)
from gcs.service.storage.database import Database, rowcount
from gcs.service.storage.tables import (
    EventRow,
    FlightRow,
    JobRow,
    PlanRow,
    ScenarioRow,
    UploadRow,
    VehicleRow,
    now,
)


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

    async def get(self, id_: str) -> Any:
        return await self.db.run(self._get, id_)

    def _get(self, id_: str) -> Any:
        with self.db.session() as s:
            found = s.get(self.row, id_)
            if found is None:
                raise NotFound(self.kind, id_)
            return found

    async def page(self, limit: int = 100, offset: int = 0) -> list[Any]:
        """Rows oldest first, `limit` from `offset` on."""
        return await self.db.run(self._page, limit, offset)

    def _page(self, limit: int, offset: int) -> list[Any]:
        with self.db.session() as s:
            query = select(self.row).order_by(self.row.created_at).limit(limit).offset(offset)
            return list(s.scalars(query))

    async def count(self) -> int:
        return await self.db.run(self._count)

    def _count(self) -> int:
        with self.db.session() as s:
            return int(s.scalar(select(func.count()).select_from(self.row)) or 0)

    async def add(self, row: Any) -> Any:
        return await self.db.run(self._add, row)

    def _add(self, row: Any) -> Any:
        with self.db.session() as s:
            s.add(row)
        return row

    async def delete(self, id_: str) -> None:
        await self.db.run(self._delete, id_)

    def _delete(self, id_: str) -> None:
        with self.db.session() as s:
            if rowcount(s.execute(delete(self.row).where(self.row.id == id_))) == 0:
                raise NotFound(self.kind, id_)

    async def update(self, id_: str, **values: Any) -> Any:
        return await self.db.run(self._update, id_, values)

    def _update(self, id_: str, values: dict[str, Any]) -> Any:
        with self.db.session() as s:
            found = s.get(self.row, id_)
            if found is None:
                raise NotFound(self.kind, id_)
            for key, value in values.items():
                setattr(found, key, value)
            return found

    def _transition(
        self,
        id_: str,
        new: FlightState | JobState,
        table: Mapping[Any, frozenset[Any]],
        **values: Any,
    ) -> Any:
        """One conditional UPDATE: the row moves to `new` only from a state the table
        allows it from, so that two movers cannot both succeed (a late progress report
        cannot reopen a finished job, a stale write cannot undo an abort)."""
        sources = [state for state, targets in table.items() if new in targets]
        with self.db.session() as s:
            moved = rowcount(
                s.execute(
                    update(self.row)
                    .where(self.row.id == id_, self.row.state.in_(sources))
                    .values(state=new, **values)
                )
            )
            found = s.get(self.row, id_)
            if found is None:
                raise NotFound(self.kind, id_)
            if not moved:
                if isinstance(new, FlightState):
                    FlightState(found.state).check(new, id_)
                else:
                    JobState(found.state).check(new, id_)
                raise StateConflict(f"{self.kind} {id_} became {found.state} meanwhile")
            return found


class ScenarioRepository(_Repository):
    row, kind = ScenarioRow, "scenario"


class PlanRepository(_Repository):
    row, kind = PlanRow, "plan"

    async def for_scenario(self, scenario_id: str, limit: int = 100) -> list[PlanRow]:
        return await self.db.run(self._for_scenario, scenario_id, limit)

    def _for_scenario(self, scenario_id: str, limit: int) -> list[PlanRow]:
        with self.db.session() as s:
            query = select(PlanRow).where(PlanRow.scenario_id == scenario_id)
            return list(s.scalars(query.order_by(PlanRow.created_at).limit(limit)))

    async def ids_for_scenario(self, scenario_id: str) -> list[str]:
        return await self.db.run(self._ids_for_scenario, scenario_id)

    def _ids_for_scenario(self, scenario_id: str) -> list[str]:
        with self.db.session() as s:
            query = select(PlanRow.id).where(PlanRow.scenario_id == scenario_id)
            return list(s.scalars(query))


class JobRepository(_Repository):
    row, kind = JobRow, "job"

    async def update(self, id_: str, **values: Any) -> JobRow:
        row: JobRow = await super().update(id_, updated_at=now(), **values)
        return row

    async def transition(self, job_id: str, new: JobState, **values: Any) -> JobRow:
        row: JobRow = await self.db.run(
            self._transition, job_id, new, JOB_TRANSITIONS, updated_at=now(), **values
        )
        return row

    async def unfinished_for_scenario(self, scenario_id: str) -> list[JobRow]:
        return await self.db.run(self._unfinished_for_scenario, scenario_id)

    def _unfinished_for_scenario(self, scenario_id: str) -> list[JobRow]:
        with self.db.session() as s:
            query = select(JobRow).where(
                JobRow.scenario_id == scenario_id, JobRow.state.in_(["queued", "running"])
            )
            return list(s.scalars(query))


class VehicleRepository(_Repository):
    row, kind = VehicleRow, "vehicle"

    async def ids(self) -> set[str]:
        """Every registered vehicle's id (what a service compares its links with once a
        second: no rows loaded)."""
        return await self.db.run(self._ids)

    def _ids(self) -> set[str]:
        with self.db.session() as s:
            return set(s.scalars(select(VehicleRow.id)))

    async def by_connection(self, connection: str, sysid: int | None) -> VehicleRow | None:
        return await self.db.run(self._by_connection, connection, sysid)

    def _by_connection(self, connection: str, sysid: int | None) -> VehicleRow | None:
        """The vehicle at this endpoint that `sysid` would also name: the same system id,
        or either side leaving it open (the first autopilot heard)."""
        with self.db.session() as s:
            rows = s.scalars(select(VehicleRow).where(VehicleRow.connection == connection))
            for row in rows:
                if sysid is None or row.sysid is None or row.sysid == sysid:
                    return row
            return None


class FlightRepository(_Repository):
    row, kind = FlightRow, "flight"

    async def transition(self, flight_id: str, new: FlightState, note: str = "") -> FlightRow:
        """Move the flight to `new` if the transition table allows it from its state now
        (StateConflict if not), with why in `note`."""
        row: FlightRow = await self.db.run(
            self._transition, flight_id, new, FLIGHT_TRANSITIONS, note=note, updated_at=now()
        )
        return row

    async def open_flights(self) -> list[FlightRow]:
        return await self.db.run(self._in_states, sorted(OPEN))

    def _in_states(self, states: Iterable[str]) -> list[FlightRow]:
        with self.db.session() as s:
            query = select(FlightRow).where(FlightRow.state.in_(list(states)))
            return list(s.scalars(query.order_by(FlightRow.created_at)))

    async def for_plans(self, plan_ids: list[str]) -> list[FlightRow]:
        return await self.db.run(self._for_plans, plan_ids)

    def _for_plans(self, plan_ids: list[str]) -> list[FlightRow]:
        with self.db.session() as s:
            query = select(FlightRow).where(FlightRow.plan_id.in_(plan_ids))
            return list(s.scalars(query))

    async def record_events(self, rows: list[EventRow]) -> None:
        """Several events in one transaction (the event writer batches them)."""
        await self.db.run(self._record_events, rows)

    def _record_events(self, rows: list[EventRow]) -> None:
        with self.db.session() as s:
            s.add_all(rows)

    async def events(self, flight_id: str, after: int = 0, limit: int = 1000) -> list[EventRow]:
        return await self.db.run(self._events, flight_id, after, limit)

    def _events(self, flight_id: str, after: int, limit: int) -> list[EventRow]:
        with self.db.session() as s:
            query = (
                select(EventRow)
                .where(EventRow.flight_id == flight_id, EventRow.id > after)
                .order_by(EventRow.id)
                .limit(limit)
            )
            return list(s.scalars(query))

    async def record_upload(self, row: UploadRow) -> UploadRow:
        added: UploadRow = await self.add(row)
        return added

    async def uploads(self, flight_id: str) -> list[UploadRow]:
        return await self.db.run(self._uploads, flight_id)

    def _uploads(self, flight_id: str) -> list[UploadRow]:
        with self.db.session() as s:
            query = select(UploadRow).where(UploadRow.flight_id == flight_id)
            return list(s.scalars(query.order_by(UploadRow.id)))

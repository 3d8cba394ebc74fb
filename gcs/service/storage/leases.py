"""Leases: which service controls a flight and runs a job, when several services share one
database. Every claim is one conditional UPDATE (a row is taken only while nobody holds
it, its holder is this service, or its holder's lease has run out), so two services
racing for one row cannot both win, on PostgreSQL as on SQLite; a holder keeps its rows
by renewing them all in one UPDATE a second. Nothing here waits on a lock held by
another service: a dead holder is simply one whose lease has expired.

The times are the services' own clocks (UTC): services sharing a database must keep
their clocks together (NTP), well within a lease.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import bindparam, select, update

from gcs.service.states import OPEN, JobState
from gcs.service.storage.database import Database, rowcount, unheld
from gcs.service.storage.tables import FlightRow, JobRow, now

UNFINISHED_JOBS = (JobState.QUEUED.value, JobState.RUNNING.value)
INTERRUPTED_JOB = "the service that ran it stopped"

# What every service runs once a `renew_s` for as long as it lives, built once: on the
# tables (no ORM session to bring up to date), the holder and the times as parameters.
_FLIGHTS = FlightRow.metadata.tables[FlightRow.__tablename__]
_JOBS = JobRow.metadata.tables[JobRow.__tablename__]
_OPEN = sorted(OPEN)
_MINE = _FLIGHTS.c.owner_id == bindparam("holder")
_RENEW_FLIGHTS = (
    update(_FLIGHTS)
    .where(_MINE, _FLIGHTS.c.state.in_(_OPEN))
    .values(lease_expires_at=bindparam("until"))
)
_RENEW_JOBS = (
    update(_JOBS)
    .where(_JOBS.c.owner_id == bindparam("holder"), _JOBS.c.state.in_(UNFINISHED_JOBS))
    .values(lease_expires_at=bindparam("until"))
)
_HELD = select(_FLIGHTS.c.id).where(_MINE, _FLIGHTS.c.state.in_(_OPEN))
_INTERRUPT_ORPHAN_JOBS = (
    update(_JOBS)
    .where(
        _JOBS.c.state.in_(UNFINISHED_JOBS),
        _JOBS.c.owner_id != bindparam("holder"),
        _JOBS.c.lease_expires_at < bindparam("now"),
    )
    .values(
        state=JobState.INTERRUPTED.value, error=INTERRUPTED_JOB, updated_at=bindparam("updated")
    )
)
_ORPHANS = (
    select(FlightRow)
    .where(
        FlightRow.state.in_(_OPEN),
        FlightRow.owner_id.is_not(None),
        FlightRow.owner_id != bindparam("holder"),
        FlightRow.lease_expires_at < bindparam("now"),
    )
    .order_by(FlightRow.created_at)
)


@dataclass(frozen=True)
class Holder:
    """A service as a lease holder: its id and the base URL where it answers."""

    id: str
    url: str


@dataclass(frozen=True)
class Renewal:
    """What one renewal found: the open flights this service still holds, how many jobs
    it renewed, how many jobs of dead services it interrupted, and the open flights dead
    services left (`orphans`)."""

    flights: frozenset[str]
    jobs: int
    interrupted_jobs: int
    orphans: list[FlightRow]


class LeaseRepository:
    def __init__(self, db: Database, holder: Holder, lease_s: float) -> None:
        self.db, self.holder, self.lease_s = db, holder, lease_s

    def _until(self) -> datetime:
        return now() + timedelta(seconds=self.lease_s)

    # --- flights -------------------------------------------------------------------------

    async def claim_flight(self, flight_id: str) -> bool:
        """Take the flight (or keep it); False if another live service holds it."""
        return await self.db.run(self._claim_flight, flight_id)

    def _claim_flight(self, flight_id: str) -> bool:
        with self.db.session() as s:
            claimed = s.execute(
                update(FlightRow)
                .where(FlightRow.id == flight_id, unheld(FlightRow, self.holder.id))
                .values(
                    owner_id=self.holder.id,
                    owner_url=self.holder.url,
                    lease_expires_at=self._until(),
                )
            )
            return rowcount(claimed) == 1

    async def release(self) -> None:
        """Let every flight this service holds go at once (a clean stop): another service
        takes them over without waiting for the lease to run out."""
        await self.db.run(self._release)

    def _release(self) -> None:
        with self.db.session() as s:
            s.execute(
                update(FlightRow)
                .where(FlightRow.owner_id == self.holder.id)
                .values(lease_expires_at=now())
            )

    # --- jobs ------------------------------------------------------------------------------

    async def claim_job(self, job_id: str) -> bool:
        """Take a queued job to run it; False if any service has taken it already: a job
        is run once (one whose service died is interrupted, never taken again)."""
        return await self.db.run(self._claim_job, job_id)

    def _claim_job(self, job_id: str) -> bool:
        with self.db.session() as s:
            claimed = s.execute(
                update(JobRow)
                .where(
                    JobRow.id == job_id,
                    JobRow.state == JobState.QUEUED.value,
                    JobRow.owner_id.is_(None),
                )
                .values(owner_id=self.holder.id, lease_expires_at=self._until())
            )
            return rowcount(claimed) == 1

    # --- both --------------------------------------------------------------------------------

    async def renew(self) -> Renewal:
        """Push this service's leases on, interrupt the jobs of dead services and find the
        flights they left: what a service does once a `renew_s`, in one transaction."""
        return await self.db.run(self._renew)

    def _renew(self) -> Renewal:
        holder, moment = self.holder.id, now()
        renewing = {"holder": holder, "until": moment + timedelta(seconds=self.lease_s)}
        dead = {"holder": holder, "now": moment}
        with self.db.session() as s:
            s.execute(_RENEW_FLIGHTS, renewing)
            jobs = rowcount(s.execute(_RENEW_JOBS, renewing))
            held = frozenset(s.scalars(_HELD, renewing))
            interrupted = rowcount(s.execute(_INTERRUPT_ORPHAN_JOBS, {**dead, "updated": moment}))
            return Renewal(held, jobs, interrupted, list(s.scalars(_ORPHANS, dead)))

    async def holder_of(self, flight_id: str) -> tuple[Holder | None, bool]:
        """Who holds the flight, and whether their lease is still running."""
        return await self.db.run(self._holder_of, flight_id)

    def _holder_of(self, flight_id: str) -> tuple[Holder | None, bool]:
        with self.db.session() as s:
            row = s.get(FlightRow, flight_id)
            if row is None or row.owner_id is None:
                return None, False
            expires = row.lease_expires_at
            live = expires is not None and _aware(expires) >= now()
            return Holder(row.owner_id, row.owner_url or ""), live


def _aware(moment: datetime) -> datetime:
    """SQLite gives timestamps back without their zone; they were stored in UTC."""
    return moment if moment.tzinfo is not None else moment.replace(tzinfo=now().tzinfo)

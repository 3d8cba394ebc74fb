"""The schema's versions, on SQLite and PostgreSQL: every migration goes up, down and up
again; the migrations build exactly what tables.py describes; a database made before
versioning (today's `create_all`, or an older one lacking columns) upgrades with its
rows; one that a newer version migrated is refused, in one line from the command line."""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import pytest
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import Engine, create_engine, inspect, text

from gcs.cli.main import main
from gcs.service.storage import (
    Database,
    FlightRepository,
    JobRepository,
    PlanRepository,
    ScenarioRepository,
    VehicleRepository,
    schema,
)
from gcs.service.storage.migrations.__main__ import draft
from gcs.service.storage.tables import Base, FlightRow

# What `Base.metadata.create_all` made before versioning (tables.py at 4f50095), in each
# dialect: {stamp} is the timestamp type, {serial} the auto-numbered key.
HEAD_ERA_TABLES = """
CREATE TABLE scenarios (id VARCHAR(12) NOT NULL, name VARCHAR(200) NOT NULL,
    body JSON NOT NULL, created_at {stamp} NOT NULL, PRIMARY KEY (id));
CREATE TABLE vehicles (id VARCHAR(12) NOT NULL, name VARCHAR(100) NOT NULL,
    connection VARCHAR(200) NOT NULL, sysid INTEGER, signing_key TEXT,
    created_at {stamp} NOT NULL, PRIMARY KEY (id), UNIQUE (connection, sysid));
CREATE TABLE jobs (id VARCHAR(12) NOT NULL, scenario_id VARCHAR(12) NOT NULL,
    settings JSON NOT NULL, state VARCHAR(16) NOT NULL, percent FLOAT NOT NULL,
    best_cost FLOAT, first_safe_s FLOAT, plan_id VARCHAR(12), error TEXT,
    created_at {stamp} NOT NULL, updated_at {stamp} NOT NULL, PRIMARY KEY (id),
    FOREIGN KEY(scenario_id) REFERENCES scenarios (id) ON DELETE CASCADE);
CREATE TABLE plans (id VARCHAR(12) NOT NULL, scenario_id VARCHAR(12) NOT NULL,
    feasible BOOLEAN NOT NULL, body JSON NOT NULL, created_at {stamp} NOT NULL,
    PRIMARY KEY (id), FOREIGN KEY(scenario_id) REFERENCES scenarios (id) ON DELETE CASCADE);
CREATE TABLE flights (id VARCHAR(12) NOT NULL, plan_id VARCHAR(12) NOT NULL,
    bindings JSON NOT NULL, options JSON NOT NULL, state VARCHAR(16) NOT NULL,
    note TEXT DEFAULT '' NOT NULL, created_at {stamp} NOT NULL, updated_at {stamp},
    PRIMARY KEY (id), FOREIGN KEY(plan_id) REFERENCES plans (id) ON DELETE CASCADE);
CREATE TABLE events (id {serial} NOT NULL, flight_id VARCHAR(12) NOT NULL,
    kind VARCHAR(40) NOT NULL, uav_id VARCHAR(64), data JSON NOT NULL,
    created_at {stamp} NOT NULL, PRIMARY KEY (id),
    FOREIGN KEY(flight_id) REFERENCES flights (id) ON DELETE CASCADE);
CREATE TABLE uploads (id {serial} NOT NULL, flight_id VARCHAR(12) NOT NULL,
    uav_id VARCHAR(64) NOT NULL, vehicle_id VARCHAR(12) NOT NULL, ok BOOLEAN NOT NULL,
    items INTEGER NOT NULL, detail TEXT NOT NULL, mission JSON, created_at {stamp} NOT NULL,
    PRIMARY KEY (id), FOREIGN KEY(flight_id) REFERENCES flights (id) ON DELETE CASCADE);
"""
TYPES = {
    "sqlite": {"stamp": "DATETIME", "serial": "INTEGER"},
    "postgresql": {"stamp": "TIMESTAMP WITH TIME ZONE", "serial": "SERIAL"},
}
LATER_COLUMNS = {"flights": "note", "jobs": "first_safe_s", "vehicles": "signing_key"}
"""Columns that data directories from before them lack (the hand migration added them)."""
WHEN = "2026-12-01 10:00:00+00:00"
JOIN_TIMEOUT_S = 60.0
"""Without the upgrade's lock, concurrent starts can wait on each other for ever."""
ROWS: list[tuple[str, dict[str, Any]]] = [
    ("scenarios", {"id": "s1", "name": "case", "body": {"uavs": [1, 2]}, "created_at": WHEN}),
    ("plans", {"id": "p1", "scenario_id": "s1", "feasible": True, "body": {"paths": [[0.5]]}}),
    ("jobs", {"id": "j1", "scenario_id": "s1", "settings": {"seed": 7}, "state": "done"}),
    ("vehicles", {"id": "v1", "name": "one", "connection": "tcp:127.0.0.1:5760", "sysid": 1}),
    ("flights", {"id": "f1", "plan_id": "p1", "bindings": {"uav1": "v1"}, "options": {}}),
    ("events", {"flight_id": "f1", "kind": "FlightEnded", "uav_id": None, "data": {"a": 1}}),
    ("uploads", {"flight_id": "f1", "uav_id": "uav1", "vehicle_id": "v1", "ok": True}),
]
DEFAULTS: dict[str, dict[str, Any]] = {
    "plans": {"created_at": WHEN},
    "jobs": {"percent": 100.0, "created_at": WHEN, "updated_at": WHEN},
    "vehicles": {"created_at": WHEN},
    "flights": {"state": "landed", "created_at": WHEN, "note": "down"},
    "events": {"created_at": WHEN},
    "uploads": {"items": 3, "detail": "", "mission": None, "created_at": WHEN},
}


def _config_run(engine: Engine, action: str, revision: str) -> None:
    with engine.begin() as connection:
        getattr(command, action)(schema.alembic_config(connection), revision)


def _diff(engine: Engine) -> list[Any]:
    with engine.connect() as connection:
        context = MigrationContext.configure(connection, opts={"compare_type": True})
        return list(compare_metadata(context, Base.metadata))


def _shape(engine: Engine) -> dict[str, Any]:
    """Every table's columns (name, type, nullable, default), indexes and constraints,
    comparable as values."""
    found = inspect(engine)
    return {
        table: (
            [(c["name"], str(c["type"]), c["nullable"], c["default"]) for c in columns],
            sorted((i["name"], tuple(i["column_names"])) for i in found.get_indexes(table)),
            sorted(str(u["column_names"]) for u in found.get_unique_constraints(table)),
            sorted(str(f["referred_table"]) for f in found.get_foreign_keys(table)),
        )
        for (_, table), columns in found.get_multi_columns().items()
        if table != "alembic_version"
    }


def _user_tables(engine: Engine) -> set[str]:
    return set(inspect(engine).get_table_names()) - {"alembic_version"}


def test_every_migration_goes_up_down_and_up_again(database_url: str) -> None:
    engine = create_engine(database_url)
    try:
        previous = "base"
        for revision in schema.revisions():
            _config_run(engine, "upgrade", revision)
            after_up = _shape(engine)
            _config_run(engine, "downgrade", previous)
            assert _shape(engine) != after_up, f"{revision} changed nothing down"
            _config_run(engine, "upgrade", revision)
            assert _shape(engine) == after_up, revision
            with engine.connect() as connection:
                assert schema.current(connection) == revision
            previous = revision
        assert _diff(engine) == []
        _config_run(engine, "downgrade", "base")
        assert _user_tables(engine) == set()
    finally:
        engine.dispose()


def test_the_models_and_the_migrations_agree(database_url: str) -> None:
    Database(database_url).close()
    engine = create_engine(database_url)
    try:
        assert _diff(engine) == []
        assert _user_tables(engine) == set(Base.metadata.tables)
    finally:
        engine.dispose()


def test_a_draft_revision_against_head_is_empty(tmp_path: Path) -> None:
    """The developer's tool (python -m gcs.service.storage.migrations) finds nothing to
    add when tables.py and the revisions agree, and numbers its draft after the head."""
    path = draft("nothing new", f"sqlite:///{tmp_path / 'draft.db'}", tmp_path)
    assert path.name == f"{int(schema.head()) + 1:04d}_nothing_new.py"
    body = path.read_text()
    assert f"down_revision = {schema.head()!r}" in body
    assert "op." not in body.replace("from alembic import op", ""), body


def _head_era_database(url: str, lacking: dict[str, str]) -> None:
    """The tables and rows a data directory made by the hand-migrated schema has, less
    the `lacking` columns (table -> column) of a directory older still."""
    engine = create_engine(url)
    with engine.begin() as connection:
        ddl = HEAD_ERA_TABLES.format(**TYPES[engine.dialect.name])
        for statement in filter(str.strip, ddl.split(";")):
            connection.execute(text(statement))
        for table, column in lacking.items():
            connection.execute(text(f"ALTER TABLE {table} DROP COLUMN {column}"))
        for table, row in ROWS:
            values = {**row, **DEFAULTS.get(table, {})}
            values = {k: v for k, v in values.items() if lacking.get(table) != k}
            values = {k: json.dumps(v) if isinstance(v, dict) else v for k, v in values.items()}
            names = ", ".join(values)
            marks = ", ".join(f":{name}" for name in values)
            connection.execute(text(f"INSERT INTO {table} ({names}) VALUES ({marks})"), values)
    engine.dispose()


@pytest.mark.parametrize("lacking", [{}, LATER_COLUMNS], ids=["today", "older"])
async def test_a_database_from_before_versioning_upgrades_with_its_rows(
    database_url: str, lacking: dict[str, str]
) -> None:
    _head_era_database(database_url, lacking)
    db = Database(database_url)
    try:
        with db.engine.connect() as connection:
            assert schema.current(connection) == schema.head()
        assert _diff(db.engine) == []
        scenario = await ScenarioRepository(db).get("s1")
        assert (scenario.name, scenario.body) == ("case", {"uavs": [1, 2]})
        assert (await PlanRepository(db).get("p1")).body == {"paths": [[0.5]]}
        job = await JobRepository(db).get("j1")
        assert (job.settings, job.state, job.first_safe_s) == ({"seed": 7}, "done", None)
        vehicle = await VehicleRepository(db).get("v1")
        assert (vehicle.connection, vehicle.sysid, vehicle.signing_key) == (
            "tcp:127.0.0.1:5760",
            1,
            None,
        )
        flights = FlightRepository(db)
        flight = await flights.get("f1")
        assert (flight.state, flight.bindings) == ("landed", {"uav1": "v1"})
        assert flight.note == ("" if "flights" in lacking else "down")
        assert [(e.kind, e.data) for e in await flights.events("f1")] == [("FlightEnded", {"a": 1})]
        assert [(u.uav_id, u.items) for u in await flights.uploads("f1")] == [("uav1", 3)]
        new_flight = await flights.add(FlightRow(plan_id="p1", bindings={}, options={}))
        assert (await flights.get(new_flight.id)).note == ""  # the columns work for new rows
    finally:
        db.close()


def _stamp_from_the_future(url: str) -> None:
    Database(url).close()
    engine = create_engine(url)
    with engine.begin() as connection:
        connection.execute(text("UPDATE alembic_version SET version_num = '9999_future'"))
    engine.dispose()


def test_a_database_a_newer_version_migrated_is_refused(database_url: str) -> None:
    _stamp_from_the_future(database_url)
    with pytest.raises(schema.SchemaTooNew) as refused:
        Database(database_url)
    message = str(refused.value)
    assert "'9999_future'" in message and f"{schema.head()!r}" in message, message
    assert "newer mvo-gcs" in message and "nothing was changed" in message, message
    engine = create_engine(database_url)
    with engine.connect() as connection:
        assert schema.current(connection) == "9999_future"
    engine.dispose()


def test_the_command_line_refuses_it_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = tmp_path / "data"
    data.mkdir()
    _stamp_from_the_future(f"sqlite:///{data / 'mvo-gcs.db'}")
    with pytest.raises(SystemExit) as exited:
        main(["serve", "--data-dir", str(data)])
    assert exited.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("mvo-gcs: error: the database sqlite:///") and "'9999_future'" in err
    assert "Traceback" not in err and err.count("\n") == 1, err


def test_two_services_starting_on_one_new_database_take_turns(postgres: Any) -> None:
    """The upgrade holds an advisory lock: the second waits, then finds it done."""
    with postgres.database() as url:
        errors: list[BaseException] = []

        def start() -> None:
            try:
                Database(url).close()
            except BaseException as exc:
                errors.append(exc)

        threads = [threading.Thread(target=start, daemon=True) for _ in range(3)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(JOIN_TIMEOUT_S)
        assert not any(t.is_alive() for t in threads), "the starts are stuck on each other"
        assert errors == []
        engine = create_engine(url)
        assert _diff(engine) == []
        engine.dispose()

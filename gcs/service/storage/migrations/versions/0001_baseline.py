"""The schema as it was when versioning began: seven tables.

A database made before versioning (by `create_all`, with columns added by hand since)
already has these tables. It keeps them and their rows: each gets only the columns it
lacks (a data directory older than `flights.note`, say), nullable or with their
default as the service used to add them, and the database is then stamped with this
revision like any other.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def _when(name: str, nullable: bool = False) -> sa.Column[object]:
    return sa.Column(name, sa.DateTime(timezone=True), nullable=nullable)


def _flight_id() -> sa.Column[str]:
    return sa.Column(
        "flight_id", sa.String(12), sa.ForeignKey("flights.id", ondelete="CASCADE"), nullable=False
    )


def _schema() -> sa.MetaData:
    """The tables as of this revision, frozen here: tables.py moves on, this does not."""
    metadata = sa.MetaData()
    sa.Table(
        "scenarios",
        metadata,
        sa.Column("id", sa.String(12), primary_key=True),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("body", sa.JSON(), nullable=False),
        _when("created_at"),
    )
    sa.Table(
        "plans",
        metadata,
        sa.Column("id", sa.String(12), primary_key=True),
        sa.Column(
            "scenario_id",
            sa.String(12),
            sa.ForeignKey("scenarios.id", ondelete="CASCADE"),
            nullable=False,
        ),
        sa.Column("feasible", sa.Boolean(), nullable=False),
        sa.Column("body", sa.JSON(), nullable=False),
        _when("created_at"),
    )
    sa.Table(
        "jobs",
        metadata,
        sa.Column("id", sa.String(12), primary_key=True),
        sa.Column(
            "scenario_id",
            sa.String(12),
            sa.ForeignKey("scenarios.id", ondelete="CASCADE"),
            nullable=False,
        ),
        sa.Column("settings", sa.JSON(), nullable=False),
        sa.Column("state", sa.String(16), nullable=False),
        sa.Column("percent", sa.Float(), nullable=False),
        sa.Column("best_cost", sa.Float(), nullable=True),
        sa.Column("first_safe_s", sa.Float(), nullable=True),
        sa.Column("plan_id", sa.String(12), nullable=True),
        sa.Column("error", sa.Text(), nullable=True),
        _when("created_at"),
        _when("updated_at"),
    )
    sa.Table(
        "vehicles",
        metadata,
        sa.Column("id", sa.String(12), primary_key=True),
        sa.Column("name", sa.String(100), nullable=False),
        sa.Column("connection", sa.String(200), nullable=False),
        sa.Column("sysid", sa.Integer(), nullable=True),
        sa.Column("signing_key", sa.Text(), nullable=True),
        _when("created_at"),
        sa.UniqueConstraint("connection", "sysid"),
    )
    sa.Table(
        "flights",
        metadata,
        sa.Column("id", sa.String(12), primary_key=True),
        sa.Column(
            "plan_id", sa.String(12), sa.ForeignKey("plans.id", ondelete="CASCADE"), nullable=False
        ),
        sa.Column("bindings", sa.JSON(), nullable=False),
        sa.Column("options", sa.JSON(), nullable=False),
        sa.Column("state", sa.String(16), nullable=False),
        sa.Column("note", sa.Text(), nullable=False, server_default=""),
        _when("created_at"),
        _when("updated_at", nullable=True),
    )
    sa.Table(
        "uploads",
        metadata,
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        _flight_id(),
        sa.Column("uav_id", sa.String(64), nullable=False),
        sa.Column("vehicle_id", sa.String(12), nullable=False),
        sa.Column("ok", sa.Boolean(), nullable=False),
        sa.Column("items", sa.Integer(), nullable=False),
        sa.Column("detail", sa.Text(), nullable=False),
        sa.Column("mission", sa.JSON(), nullable=True),
        _when("created_at"),
    )
    sa.Table(
        "events",
        metadata,
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        _flight_id(),
        sa.Column("kind", sa.String(40), nullable=False),
        sa.Column("uav_id", sa.String(64), nullable=True),
        sa.Column("data", sa.JSON(), nullable=False),
        _when("created_at"),
    )
    return metadata


def _addable(column: sa.Column[object]) -> sa.Column[object]:
    """`column` as it can be added to a table that has rows: with its default, or nullable."""
    if column.server_default is not None:
        return sa.Column(
            column.name, column.type, nullable=False, server_default=column.server_default
        )
    return sa.Column(column.name, column.type, nullable=True)


def upgrade() -> None:
    bind = op.get_bind()
    found = sa.inspect(bind)
    for table in _schema().sorted_tables:
        if not found.has_table(table.name):
            table.create(bind)
            continue
        have = {column["name"] for column in found.get_columns(table.name)}
        for column in table.columns:
            if column.name not in have:
                op.add_column(table.name, _addable(column))


def downgrade() -> None:
    for table in reversed(_schema().sorted_tables):
        op.drop_table(table.name)

"""Events indexed by flight and id: a flight's event page (`WHERE flight_id = ? AND
id > ? ORDER BY id`) reads its own rows only, not every flight's ever stored
(PostgreSQL indexes no foreign key by itself)."""

from __future__ import annotations

from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_index("ix_events_flight_id_id", "events", ["flight_id", "id"])


def downgrade() -> None:
    op.drop_index("ix_events_flight_id_id", table_name="events")

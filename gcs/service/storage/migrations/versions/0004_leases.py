"""Several services on one database (issue 27, part 4): a flight is controlled by one
service at a time and a planning job is run by the service that made it, each under a
lease the owner renews (`owner_id`, `lease_expires_at`; a flight also keeps where its
owner answers, `owner_url`). Rows from before have no owner."""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    for table in ("flights", "jobs"):
        op.add_column(table, sa.Column("owner_id", sa.String(length=200), nullable=True))
        op.add_column(
            table, sa.Column("lease_expires_at", sa.DateTime(timezone=True), nullable=True)
        )
    op.add_column("flights", sa.Column("owner_url", sa.String(length=500), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("flights") as batch:
        batch.drop_column("owner_url")
        batch.drop_column("lease_expires_at")
        batch.drop_column("owner_id")
    with op.batch_alter_table("jobs") as batch:
        batch.drop_column("lease_expires_at")
        batch.drop_column("owner_id")

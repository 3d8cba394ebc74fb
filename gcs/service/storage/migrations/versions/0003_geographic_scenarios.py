"""Geographic scenarios (issue 26): a scenario posted as GeoJSON keeps the file it was
derived from beside its grid (`scenarios.geographic`); other scenarios have none."""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("scenarios", sa.Column("geographic", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("scenarios") as batch:
        batch.drop_column("geographic")

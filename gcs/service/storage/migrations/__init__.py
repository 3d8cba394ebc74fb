"""The schema's history as Alembic migrations, shipped inside the package and run by
`gcs.service.storage.schema` when the service starts (no alembic.ini needed)."""

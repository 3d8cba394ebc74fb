"""The `mvo-gcs` command line."""

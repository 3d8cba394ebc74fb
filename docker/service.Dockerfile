# The planning service (REST + WebSocket API) with SQLite storage in a volume (or
# PostgreSQL, MVO_GCS_DATABASE_URL).
# Build from the repository root: docker build -f docker/service.Dockerfile -t mvo-gcs .
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    MVO_GCS_HOST=0.0.0.0 \
    MVO_GCS_PORT=8000 \
    MVO_GCS_DATA_DIR=/data

RUN useradd --create-home --uid 10001 gcs \
    && mkdir /data \
    && chown gcs:gcs /data

WORKDIR /app
COPY pyproject.toml README.md ./
COPY planner ./planner
COPY gcs ./gcs
COPY sitl_mock ./sitl_mock
RUN pip install --no-cache-dir "./.[dask,postgres]"

USER 10001
VOLUME ["/data"]
EXPOSE 8000

HEALTHCHECK --interval=10s --timeout=3s --start-period=20s --retries=3 \
    CMD ["python", "-c", "import sys, urllib.request; sys.exit(urllib.request.urlopen('http://127.0.0.1:8000/health/ready', timeout=2).status != 200)"]

ENTRYPOINT ["mvo-gcs", "serve"]

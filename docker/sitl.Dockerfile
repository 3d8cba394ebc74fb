# Simulated MAVLink vehicles (ArduCopter or PX4 flavour), one TCP port per vehicle.
# Build from the repository root: docker build -f docker/sitl.Dockerfile -t mvo-gcs-sitl .
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1

RUN useradd --create-home --uid 10002 sitl

WORKDIR /app
COPY pyproject.toml README.md ./
COPY planner ./planner
COPY gcs ./gcs
COPY sitl_mock ./sitl_mock
RUN pip install --no-cache-dir .

USER 10002
EXPOSE 5760-5850

# Vehicle i serves TCP 5760 + 10 (i - 1), as ArduPilot SITL: vehicle 1 on 5760.
HEALTHCHECK --interval=10s --timeout=3s --start-period=10s --retries=3 \
    CMD ["python", "-c", "import socket; socket.create_connection(('127.0.0.1', 5760), 2).close()"]

ENTRYPOINT ["python", "-m", "sitl_mock", "--transport", "tcp", "--base-port", "5760", "--bind", "0.0.0.0"]
CMD ["--vehicles", "3", "--speedup", "1"]

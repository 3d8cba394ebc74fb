"""The ground station, in layers that import only downwards (docs/ARCHITECTURE.md):

- `gcs.mavlink`: the MAVLink client (transport, connection, link, commands, mission
  protocol, telemetry, errors);
- `gcs.mission`: the mission domain (building missions from plans, files, geodesy, pacing);
- `gcs.fleet`: several vehicles flying one plan (upload, start, schedule keeping,
  separation, events);
- `gcs.service`: the REST + WebSocket service, its storage and operator console;
- `gcs.cli`: the `mvo-gcs` command line.
"""

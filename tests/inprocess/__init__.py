"""The service and simulated vehicles in the test's own process, on one virtual clock.

`InProcessService` is `create_app()` behind an in-process HTTP client (httpx's ASGI
transport, and httpx-ws for the live WebSockets); its vehicles are `SimulatedVehicles`
reached through in-memory ports instead of sockets. Tests using it are marked
`virtual_clock`: the whole flight, service timers included, runs on the virtual-time
loop, so a ten-minute flight takes seconds and a seed replays exactly. Sockets, uvicorn
and a real `mvo-gcs serve` are covered by the smoke, conformance and real-SITL tests.
"""

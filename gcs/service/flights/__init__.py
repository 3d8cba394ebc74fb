"""Flights in the service: a plan bound to vehicles, owned, operated, recorded, streamed."""

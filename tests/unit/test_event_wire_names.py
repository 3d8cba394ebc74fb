"""What clients read of a flight's end stays as it was on the wire: the outcome is an enum
in the code and its plain name in the JSON an event becomes."""

from __future__ import annotations

import json

from gcs.fleet.events import FlightEnded, FlightOutcome
from gcs.service.flights.active import event_json


def test_a_flight_outcome_is_its_wire_name_in_an_events_json() -> None:
    assert [o.value for o in FlightOutcome] == ["landed", "aborted", "timeout", "ended"]
    ended = FlightEnded(False, 7.2, ("uav1", "uav2"), FlightOutcome.TIMEOUT, at=12.5)
    message = json.loads(json.dumps(event_json(ended)))
    assert message == {
        "type": "event",
        "kind": "FlightEnded",
        "at": 12.5,
        "completed": False,
        "min_separation_m": 7.2,
        "closest_pair": ["uav1", "uav2"],
        "outcome": "timeout",
    }

"""What clients read of events stays as it was on the wire: a flight's outcome and every
event's kind are enums in the code and their plain names in the JSON an event becomes."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

from gcs.fleet.events import EventKind, FleetEvent, FlightEnded, FlightOutcome
from gcs.service.flights.active import event_json

CONSOLE = Path(__file__).parents[2] / "gcs" / "service" / "console" / "static"


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


WIRE_KINDS = [
    "Uploaded", "VehicleReady", "VehicleFailed", "MissionsStarted", "StartCancelled",
    "ItemReached", "Waiting", "WaitOver", "LeadTaken", "OperatorHeld", "OperatorContinued",
    "Withdrawn", "VehicleLinkRegained", "BrakedOnLinkLoss",
    "AddressClaimed", "Progress", "VehicleFinished", "Aborted",
    "FlightEnded", "FlightState", "ObjectReported", "OperatorCommand", "Positions",
    "TakenOver", "UnfollowedPaused", "AutoResumed", "Paused", "Resumed",
]  # fmt: skip
"""Every `kind` a client has ever been sent or a database stores: never renamed."""


def test_event_kinds_are_todays_wire_names() -> None:
    assert [k.value for k in EventKind] == WIRE_KINDS


def test_every_fleet_event_has_its_own_kind_its_class_name() -> None:
    classes = [c for c in FleetEvent.__subclasses__() if c.__module__ == "gcs.fleet.events"]
    assert len(classes) == 19
    assert len({c.kind for c in classes}) == len(classes)
    for event_class in classes:
        assert event_class.kind == event_class.__name__, event_class
        assert "kind" not in {f.name for f in dataclasses.fields(event_class)}


def test_the_console_reads_kinds_by_their_wire_names() -> None:
    source = (CONSOLE / "console.js").read_text()
    kinds = re.search(r"const KIND = Object\.freeze\(\{(.*?)\}\);", source, re.S)
    assert kinds is not None
    pairs = re.findall(r"(\w+): \"(\w+)\"", kinds.group(1))
    assert pairs and all(EventKind[name] == value for name, value in pairs), pairs
    # no kind compared as a bare string elsewhere in the page
    assert not re.findall(r"kind === \"", source)

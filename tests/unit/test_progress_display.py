"""mvo-gcs fly's progress display writes to the stdout of when it runs (one bound at
import, once swapped and closed, as pytest's capture does, made the command fail with
"I/O operation on closed file")."""

from __future__ import annotations

import io
import sys

import pytest

from gcs.cli.progress_display import ProgressDisplay, event_line
from gcs.fleet.events import LeadTaken


def test_the_display_writes_to_the_stdout_of_now(monkeypatch: pytest.MonkeyPatch) -> None:
    now = io.StringIO()
    monkeypatch.setattr(sys, "stdout", now)
    display = ProgressDisplay()
    assert display.out is now and not display.live  # not a terminal: lines, no redrawing


def test_a_lead_taken_says_who_now_waits_for_whom() -> None:
    line = event_line(LeadTaken("uav6", 1.498, (("uav6", "uav4"), ("uav1", "uav3"))))
    assert line == (
        "uav6 stopped 1.5 m inside an encounter and goes first: "
        "uav4 waits for uav6, uav3 waits for uav1"
    )

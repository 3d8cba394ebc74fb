"""A batch of fuzzed flights on every CI run: fresh seeds, the same ones every run.

FUZZ_FLIGHTS (default below) sets how many, FUZZ_FIRST_SEED where they start: a longer
campaign is `python -m tests.fuzz --seeds A:B [--workers N | --scheduler tcp://...]`."""

from __future__ import annotations

import os

import pytest

from tests.fuzz.runner import fly_seed

pytestmark = [pytest.mark.slow, pytest.mark.fuzz]

FLIGHTS = int(os.environ.get("FUZZ_FLIGHTS", "28"))
FIRST = int(os.environ.get("FUZZ_FIRST_SEED", "1000"))


@pytest.mark.parametrize("seed", range(FIRST, FIRST + FLIGHTS))
def test_a_fuzzed_flight_keeps_every_invariant(seed: int) -> None:
    report = fly_seed(seed)
    assert not report.violations, report.summary()


RESUMED = (1067, 1331)
"""Seeds whose operator restarts the service mid-flight and then resumes the flight (the
campaign's seeds above draw none that lands after a resume): a gap swap of 4 UAVs and a
random scatter of 6, over delaying, duplicating and reordering links."""


@pytest.mark.parametrize("seed", RESUMED)
def test_a_resumed_fuzzed_flight_lands_every_vehicle_at_its_goal(seed: int) -> None:
    report = fly_seed(seed)
    assert not report.violations, report.summary()
    assert any(n.startswith("resume: 200") for n in report.notes), report.summary()
    assert report.outcome == "landed", report.summary()

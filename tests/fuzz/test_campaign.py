"""A batch of fuzzed flights on every CI run: fresh seeds, the same ones every run.

FUZZ_FLIGHTS (default below) sets how many, FUZZ_FIRST_SEED where they start: a longer
campaign is `python -m tests.fuzz --seeds A:B [--workers N | --scheduler tcp://...]`."""

from __future__ import annotations

import os

import pytest

from tests.fuzz.runner import fly_seed

pytestmark = [pytest.mark.slow, pytest.mark.fuzz]

FLIGHTS = int(os.environ.get("FUZZ_FLIGHTS", "24"))
FIRST = int(os.environ.get("FUZZ_FIRST_SEED", "1000"))


@pytest.mark.parametrize("seed", range(FIRST, FIRST + FLIGHTS))
def test_a_fuzzed_flight_keeps_every_invariant(seed: int) -> None:
    report = fly_seed(seed)
    assert not report.violations, report.summary()

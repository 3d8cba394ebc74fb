"""Same seed, same plan: every flow plans the recorded set exactly as it did when recorded.

The set and how it is digested: tests/unit/plan_digests.py. The six cases run in a
couple of seconds; the generated scenarios are marked slow.
"""

from __future__ import annotations

import json

import pytest

from tests.unit import plan_digests as recorded

RECORD = json.loads(recorded.RECORD.read_text())


def scenario_names() -> list:
    return [
        pytest.param(name, marks=() if name.startswith("case-") else pytest.mark.slow)
        for name in recorded.SCENARIOS
    ]


@pytest.mark.parametrize("name", scenario_names())
def test_the_recorded_plans_are_planned_again(name: str) -> None:
    scenario = recorded.SCENARIOS[name]()
    for flow, settings in recorded.FLOWS.items():
        result, reasons = recorded.planned(scenario, settings)
        key = f"{name}/{flow}"
        assert recorded.plan_digest(result, reasons) == RECORD[key], key
        if f"{key}/live" in RECORD:
            assert recorded.live_digest(scenario, result) == RECORD[f"{key}/live"], key


def test_the_record_covers_every_case_and_flow() -> None:
    expected = {f"{s}/{f}" for s in recorded.SCENARIOS for f in recorded.FLOWS}
    expected |= {f"{s}/anytime/live" for s in recorded.LIVE_SCENARIOS}
    assert set(RECORD) == expected

"""Link faults: loss, duplication, reordering, delay and silence, deterministic per seed."""

from __future__ import annotations

import numpy as np
import pytest

from sitl_mock.faults import Faults, FaultyLink


def send_all(link: FaultyLink[int], n: int, direction: str = "out", dt: float = 0.01) -> list[int]:
    delivered: list[int] = []
    push = link.outbound if direction == "out" else link.inbound
    for i in range(n):
        now = i * dt
        delivered += push(i, now)
        inbound, outbound = link.release(now)
        delivered += outbound if direction == "out" else inbound
    for k in range(1, 200):
        inbound, outbound = link.release(n * dt + k * 0.01)
        delivered += outbound if direction == "out" else inbound
    return delivered


def test_clean_link_passes_everything_in_order():
    link: FaultyLink[int] = FaultyLink(Faults(), np.random.default_rng(0))
    assert send_all(link, 100) == list(range(100))


@pytest.mark.parametrize("direction", ["in", "out"])
def test_loss_drops_about_the_given_fraction_in_one_direction_only(direction):
    faults = Faults(loss_in=0.3) if direction == "in" else Faults(loss_out=0.3)
    link: FaultyLink[int] = FaultyLink(faults, np.random.default_rng(1))
    delivered = send_all(link, 5000, direction)
    assert 0.27 < 1 - len(delivered) / 5000 < 0.33
    other = "out" if direction == "in" else "in"
    assert len(send_all(link, 100, other)) == 100


def test_duplicates_and_reorders():
    link: FaultyLink[int] = FaultyLink(Faults(duplicate=0.2, reorder=0.1), np.random.default_rng(2))
    delivered = send_all(link, 2000)
    assert 2300 < len(delivered) < 2500
    assert sorted(set(delivered)) == list(range(2000))
    assert delivered != sorted(delivered)


def test_latency_and_jitter_delay_in_simulated_time():
    link: FaultyLink[str] = FaultyLink(
        Faults(latency_s=0.5, jitter_s=0.1), np.random.default_rng(3)
    )
    assert link.outbound("a", now=0.0) == []
    assert link.release(0.49) == ([], [])
    assert link.release(0.61) == ([], ["a"])


def test_silence_drops_both_ways_until_it_ends():
    link: FaultyLink[str] = FaultyLink(Faults(), np.random.default_rng(4))
    link.silence(until=5.0)
    assert link.inbound("x", 4.9) == [] and link.outbound("y", 4.9) == []
    assert link.inbound("x", 5.0) == ["x"]


def test_same_seed_same_choices():
    runs = [
        send_all(FaultyLink(Faults(loss_out=0.5, reorder=0.2), np.random.default_rng(7)), 500)
        for _ in range(2)
    ]
    assert runs[0] == runs[1]


@pytest.mark.parametrize("bad", [{"loss_in": 1.5}, {"latency_s": -1}, {"reject_at": "never"}])
def test_invalid_faults_are_refused(bad):
    with pytest.raises(ValueError):
        Faults(**bad)

"""Truth recording: tracks, the JSON-lines log and the minimum airborne separation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sitl_mock.geo import LocalFrame
from sitl_mock.track import SeparationMonitor, TrackRecorder


def test_separation_is_the_minimum_over_airborne_pairs_only():
    monitor = SeparationMonitor([1, 2, 3])
    positions = np.array([[0.0, 0.0], [5.0, 0.0], [1.0, 0.0]])
    monitor.update(1.0, positions, np.array([True, True, False]))
    airborne = np.array([True, True, False])
    monitor.update(2.0, positions + np.array([[0, 0], [-2, 0], [0, 0]]), airborne)
    monitor.update(3.0, positions + np.array([[0, 0], [10, 0], [0, 0]]), airborne)
    frame = LocalFrame(47.0, 8.0)
    result = monitor.result(frame.to_geodetic)
    assert result is not None
    assert result.distance_m == pytest.approx(3.0)
    assert result.t == 2.0 and result.sysids == (1, 2)
    east, north = frame.to_local(result.lat, result.lon)
    assert (east, north) == pytest.approx((1.5, 0.0), abs=1e-3)


def test_no_separation_when_never_two_airborne():
    monitor = SeparationMonitor([1, 2])
    monitor.update(1.0, np.zeros((2, 2)), np.array([True, False]))
    assert monitor.result(LocalFrame(0, 0).to_geodetic) is None


def test_tracks_per_vehicle_and_the_log_file(tmp_path):
    log = tmp_path / "track.jsonl"
    recorder = TrackRecorder([4, 7], log)
    for k in range(3):
        recorder.record(
            k * 0.1,
            np.array([1.0, 2.0]),
            np.array([3.0, 4.0]),
            np.array([k, 10.0 * k]),
            np.array([True, False]),
        )
    recorder.close()
    track = recorder.track(7)
    assert [p.alt for p in track] == [0.0, 10.0, 20.0]
    final = recorder.final(4)
    assert final is not None and final.armed is True and final.lat == 1.0
    lines = [json.loads(line) for line in log.read_text().splitlines()]
    assert len(lines) == 6
    assert lines[-1] == {"t": 0.2, "sysid": 7, "lat": 2.0, "lon": 4.0, "alt": 20.0, "armed": False}

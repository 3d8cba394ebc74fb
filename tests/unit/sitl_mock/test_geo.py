"""The simulator's local frame converts positions as pymap3d does, to the last bit (it
only works out the origin's ECEF position once): a flight replays the same either way."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest

from sitl_mock.geo import LocalFrame


def test_to_geodetic_is_pymap3d_enu2geodetic_bit_for_bit():
    rng = np.random.default_rng(23)
    for _ in range(300):
        lat, lon, alt = rng.uniform(-85, 85), rng.uniform(-180, 180), rng.uniform(-100, 4000)
        frame = LocalFrame(lat, lon, alt)
        for n in (1, 6):
            east, north = rng.uniform(-5000, 5000, n), rng.uniform(-5000, 5000, n)
            got = frame.to_geodetic(east, north)
            want = pymap3d.enu2geodetic(east, north, np.zeros_like(east), lat, lon, alt)
            np.testing.assert_array_equal(got[0], want[0])
            np.testing.assert_array_equal(got[1], want[1])


def test_the_origin_is_itself():
    frame = LocalFrame(-35.363261, 149.165230, 584.0)
    lat, lon = frame.to_geodetic(np.zeros(1), np.zeros(1))
    assert (float(lat[0]), float(lon[0])) == pytest.approx((-35.363261, 149.165230), abs=1e-12)

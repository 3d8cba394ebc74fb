"""Small flight behaviours (hold, climb, fly to, land, return home) that modes and mission
items are built from. Each sets targets on a `Body` and reports when it is done."""

from __future__ import annotations

import math
from typing import Protocol

from .codec import mavlink
from .kinematics import Body, NavLimits

ON_GROUND: int = mavlink.MAV_LANDED_STATE_ON_GROUND
IN_AIR: int = mavlink.MAV_LANDED_STATE_IN_AIR
TAKEOFF: int = mavlink.MAV_LANDED_STATE_TAKEOFF
LANDING: int = mavlink.MAV_LANDED_STATE_LANDING

LAND_SLOW_BELOW_M = 10.0
"""ArduCopter descends at its descent rate to 10 m, then at LAND_SPD_MS: it slows on the
way down as a square-root controller at its vertical acceleration would stop it at that
height, so it is at the landing speed there (SITL passed 10 m at about 0.5 m/s; the
mock, slowing only below it, reached the ground a second early)."""
TAKEOFF_DONE_MARGIN_M = 0.5


class Manoeuvre(Protocol):
    @property
    def phase(self) -> int:
        """The EXTENDED_SYS_STATE landed_state while this runs (once off the ground)."""
        ...

    def start(self, body: Body, now: float) -> None: ...

    def update(self, body: Body, now: float) -> bool:
        """Advance; True once finished."""
        ...


class Hold:
    """Brake and hover in place, forever."""

    phase = IN_AIR

    def start(self, body: Body, now: float) -> None:
        body.hold()

    def update(self, body: Body, now: float) -> bool:
        return False


class Stop:
    """Stop along the velocity, as a paused mission or BRAKE does (`brake`), and hover."""

    phase = IN_AIR

    def __init__(self, brake: bool = False) -> None:
        self.brake = brake

    def start(self, body: Body, now: float) -> None:
        body.stop(self.brake)

    def update(self, body: Body, now: float) -> bool:
        return False


class Climb:
    """Vertical take-off to an altitude above home; done at once if already there."""

    phase = TAKEOFF

    def __init__(self, alt: float) -> None:
        self.alt = alt

    def start(self, body: Body, now: float) -> None:
        if body.alt < self.alt - TAKEOFF_DONE_MARGIN_M:
            body.hold(alt=self.alt)

    def update(self, body: Body, now: float) -> bool:
        return body.alt >= self.alt - TAKEOFF_DONE_MARGIN_M and (
            body.reached or body.alt >= self.alt - 0.1
        )


class FlyTo:
    """Fly to a point and stop there (and hold), or round the corner into the leg to `then`."""

    phase = IN_AIR

    def __init__(
        self,
        east: float,
        north: float,
        alt: float,
        radius: float,
        then: tuple[float, float] | None = None,
        hold_s: float = 0.0,
    ) -> None:
        self.east, self.north, self.alt = east, north, alt
        self.radius, self.then, self.hold_s = radius, then, hold_s
        self._arrived_at: float | None = None

    def start(self, body: Body, now: float) -> None:
        self._arrived_at = None
        body.go_to(self.east, self.north, self.alt, self.radius, self.then)

    @property
    def arrived(self) -> bool:
        return self._arrived_at is not None

    def update(self, body: Body, now: float) -> bool:
        if self._arrived_at is None:
            if not body.reached:
                return False
            self._arrived_at = now
        return now - self._arrived_at >= self.hold_s


class Land:
    """Descend where the vehicle stops, slowing to the landing speed near the ground."""

    phase = LANDING

    def __init__(self, limits: NavLimits) -> None:
        self.limits = limits

    def start(self, body: Body, now: float) -> None:
        body.set_descent(self.limits.descent_rate)
        body.stop(alt=-1.0)  # aim below the ground so the descent does not flare

    def update(self, body: Body, now: float) -> bool:
        limits, above = self.limits, max(body.alt - LAND_SLOW_BELOW_M, 0.0)
        slowing = math.sqrt(2 * limits.vertical_accel * above)
        body.set_descent(min(limits.descent_rate, max(limits.land_speed, slowing)))
        return body.alt <= 0.0


class Sequence:
    """Manoeuvres one after another."""

    def __init__(self, *steps: Manoeuvre) -> None:
        self.steps = steps
        self._index = 0

    @property
    def current(self) -> Manoeuvre:
        return self.steps[min(self._index, len(self.steps) - 1)]

    @property
    def phase(self) -> int:
        return self.current.phase

    def start(self, body: Body, now: float) -> None:
        self._index = 0
        self.steps[0].start(body, now)

    def update(self, body: Body, now: float) -> bool:
        while self.steps[self._index].update(body, now):
            self._index += 1
            if self._index == len(self.steps):
                self._index -= 1
                return True
            self.steps[self._index].start(body, now)
        return False


class _ClimbInPlace(Climb):
    phase = IN_AIR


def return_home(
    body: Body, home_en: tuple[float, float], rtl_alt: float, limits: NavLimits
) -> Sequence:
    """RTL: climb to the return altitude if below it, fly home, land."""
    alt = max(body.alt, rtl_alt)
    return Sequence(
        _ClimbInPlace(alt),
        FlyTo(home_en[0], home_en[1], alt, radius=limits.accept_radius),
        Land(limits),
    )


def land_at(east: float, north: float, body: Body, limits: NavLimits) -> Sequence:
    """NAV_LAND with a position: fly there at the current altitude, then land."""
    return Sequence(FlyTo(east, north, body.alt, radius=limits.accept_radius), Land(limits))

"""Point-mass kinematics for the whole fleet, stepped together with numpy.

Each vehicle chases a target: horizontally at up to its cruise speed with a bounded
acceleration, arriving with an `exit_speed` (non-zero to carry speed through a corner, zero
to stop there); vertically at its climb or descent rate with its own acceleration bound.
Altitude is metres above the vehicle's home and never goes below the ground (0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STOPPED_SPEED = 0.3
"""m/s: a vehicle told to stop at a target counts as arrived below this speed."""
VERTICAL_TOLERANCE = 0.3
"""m: close enough to a target altitude."""


@dataclass(frozen=True)
class NavLimits:
    """Navigation limits in SI units (read from an autopilot's parameters)."""

    cruise_speed: float = 10.0
    accel: float = 2.5
    climb_rate: float = 2.5
    descent_rate: float = 1.5
    vertical_accel: float = 1.0
    land_speed: float = 0.5
    accept_radius: float = 2.0


class PointMassFleet:
    """Positions (east, north, alt), velocities and targets of n vehicles in one local frame."""

    def __init__(self, homes_en: np.ndarray) -> None:
        n = len(homes_en)
        self.pos = np.zeros((n, 3))
        self.pos[:, :2] = homes_en
        self.vel = np.zeros((n, 3))
        self.target = self.pos.copy()
        self.exit_speed = np.zeros(n)
        self.radius = np.full(n, 2.0)
        self.cruise = np.full(n, 10.0)
        self.accel = np.full(n, 2.5)
        self.climb = np.full(n, 2.5)
        self.descent = np.full(n, 1.5)
        self.vertical_accel = np.full(n, 1.0)
        self.active = np.zeros(n, dtype=bool)
        """Motors driving the point mass; inactive vehicles stand still."""
        self.reached = np.zeros(n, dtype=bool)
        """Latched once a vehicle meets its current target; cleared by a new target."""

    def __len__(self) -> int:
        return len(self.pos)

    def step(self, dt: float) -> None:
        self._step_horizontal(dt)
        self._step_vertical(dt)
        self.vel[~self.active] = 0.0
        self.pos += self.vel * dt
        on_ground = self.pos[:, 2] <= 0.0
        self.pos[on_ground, 2] = 0.0
        self.vel[on_ground & (self.vel[:, 2] < 0), 2] = 0.0
        self.reached |= self._arrived()

    def _step_horizontal(self, dt: float) -> None:
        to_target = self.target[:, :2] - self.pos[:, :2]
        dist = np.hypot(to_target[:, 0], to_target[:, 1])
        stopping = self.exit_speed <= 0
        # pass through at exit_speed from the edge of the acceptance radius; stop at the point
        braking = np.where(stopping, dist, np.maximum(dist - self.radius, 0.0))
        speed = np.minimum(self.cruise, np.sqrt(self.exit_speed**2 + 2 * self.accel * braking))
        speed[stopping] = np.minimum(speed[stopping], dist[stopping] / dt)
        direction = np.divide(
            to_target, dist[:, None], out=np.zeros_like(to_target), where=dist[:, None] > 1e-9
        )
        self.vel[:, :2] += _limit(direction * speed[:, None] - self.vel[:, :2], self.accel * dt)

    def _step_vertical(self, dt: float) -> None:
        error = self.target[:, 2] - self.pos[:, 2]
        rate = np.where(error > 0, self.climb, self.descent)
        speed = np.minimum(rate, np.sqrt(2 * self.vertical_accel * np.abs(error)))
        speed = np.minimum(speed, np.abs(error) / dt)
        change = np.sign(error) * speed - self.vel[:, 2]
        limit = self.vertical_accel * dt
        self.vel[:, 2] += np.clip(change, -limit, limit)

    def _arrived(self) -> np.ndarray:
        to_target = self.target - self.pos
        dist = np.hypot(to_target[:, 0], to_target[:, 1])
        speed = np.hypot(self.vel[:, 0], self.vel[:, 1])
        horizontal = (dist <= self.radius) & ((self.exit_speed > 0) | (speed < STOPPED_SPEED))
        return self.active & horizontal & (np.abs(to_target[:, 2]) < VERTICAL_TOLERANCE)

    def body(self, index: int) -> Body:
        return Body(self, index)


def _limit(vectors: np.ndarray, max_norm: np.ndarray) -> np.ndarray:
    norm = np.hypot(vectors[:, 0], vectors[:, 1])
    scale = np.minimum(1.0, np.divide(max_norm, norm, out=np.ones_like(norm), where=norm > 0))
    return vectors * scale[:, None]


class Body:
    """One vehicle's handle on the fleet arrays: where it is and where it should go."""

    def __init__(self, fleet: PointMassFleet, index: int) -> None:
        self._fleet = fleet
        self.index = index

    @property
    def position(self) -> np.ndarray:
        """(east, north, alt above home), a copy."""
        return self._fleet.pos[self.index].copy()

    @property
    def velocity(self) -> np.ndarray:
        return self._fleet.vel[self.index].copy()

    @property
    def alt(self) -> float:
        return float(self._fleet.pos[self.index, 2])

    @property
    def ground_speed(self) -> float:
        vx, vy = self._fleet.vel[self.index, :2]
        return float(np.hypot(vx, vy))

    @property
    def reached(self) -> bool:
        return bool(self._fleet.reached[self.index])

    @property
    def active(self) -> bool:
        return bool(self._fleet.active[self.index])

    def set_active(self, active: bool) -> None:
        self._fleet.active[self.index] = active

    def apply_limits(self, limits: NavLimits) -> None:
        f, i = self._fleet, self.index
        f.cruise[i], f.accel[i] = limits.cruise_speed, limits.accel
        f.climb[i], f.descent[i] = limits.climb_rate, limits.descent_rate
        f.vertical_accel[i] = limits.vertical_accel

    def set_cruise(self, speed: float) -> None:
        self._fleet.cruise[self.index] = speed

    def set_descent(self, rate: float) -> None:
        self._fleet.descent[self.index] = rate

    def go_to(
        self, east: float, north: float, alt: float, radius: float, exit_speed: float = 0.0
    ) -> None:
        f, i = self._fleet, self.index
        f.target[i] = (east, north, alt)
        f.radius[i] = max(radius, 0.1)
        f.exit_speed[i] = exit_speed
        f.reached[i] = False

    def stopping_point(self) -> tuple[float, float]:
        """Where braking at the acceleration limit would end."""
        f, i = self._fleet, self.index
        vel = f.vel[i, :2]
        return tuple(f.pos[i, :2] + vel * np.hypot(*vel) / (2 * f.accel[i]))

    def hold(self, alt: float | None = None) -> None:
        """Brake to a stop and stay there (at `alt`, default the current altitude)."""
        east, north = self.stopping_point()
        self.go_to(east, north, self.alt if alt is None else alt, radius=0.5)

    def place(self, east: float, north: float, alt: float = 0.0) -> None:
        """Teleport at rest (a reboot puts the vehicle back on its home)."""
        f, i = self._fleet, self.index
        f.pos[i] = (east, north, alt)
        f.vel[i] = 0.0
        self.go_to(east, north, alt, radius=0.5)

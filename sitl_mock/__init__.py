"""Simulated MAVLink vehicles (ArduCopter or PX4 flavour) that stand in for SITL.

Each vehicle speaks MAVLink 2 over a real UDP or TCP socket, answers ground stations the
way the real autopilot does, and flies the mission it holds in simulated time::

    sim = Simulator([VehicleConfig(sysid=1, home=(47.39, 8.54, 488.0))], speedup=20.0)
    with sim.running():
        link = sim.connection_string(1)   # "udpout:127.0.0.1:<port>"
        ...
        sim.track(1); sim.min_separation()

It imports nothing from `planner` or `gcs`.
"""

from .faults import Faults
from .mission_item import MissionItem
from .simulator import Simulator
from .snapshot import VehicleState
from .track import Separation, TrackPoint
from .vehicle import VehicleConfig

__all__ = [
    "Faults",
    "MissionItem",
    "Separation",
    "Simulator",
    "TrackPoint",
    "VehicleConfig",
    "VehicleState",
]

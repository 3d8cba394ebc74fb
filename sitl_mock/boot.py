"""A vehicle's start-up as a ground station sees it: the end of initialisation ("ArduPilot
Ready", mission storage usable, the boot mode set), home being set (GPS_GLOBAL_ORIGIN and
HOME_POSITION sent unasked), and the SYS_STATUS sensor bits of each stage.

The stages come from the vehicle's `Timeline` (readiness.py), in simulated time since the
last (re)boot. SYS_STATUS bits are those ArduCopter SITL sends: present, enabled and
healthy differ (the fence is present but not enabled; the proximity sensor is "healthy"
without being present; PREARM_CHECK is healthy only once the arming checks pass).
"""

from __future__ import annotations

from collections.abc import Callable

from .codec import mavlink as S
from .flight import FlightController
from .mission_store import MissionStore
from .snapshot import Sensors

ARDUCOPTER_PRESENT = (
    S.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | S.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | S.MAV_SYS_STATUS_SENSOR_3D_MAG
    | S.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | S.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | S.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | S.MAV_SYS_STATUS_SENSOR_YAW_POSITION
    | S.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | S.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
    | S.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | S.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
    | S.MAV_SYS_STATUS_GEOFENCE
    | S.MAV_SYS_STATUS_AHRS
    | S.MAV_SYS_STATUS_TERRAIN
    | S.MAV_SYS_STATUS_LOGGING
    | S.MAV_SYS_STATUS_SENSOR_BATTERY
    | S.MAV_SYS_STATUS_PREARM_CHECK
    | S.MAV_SYS_STATUS_SENSOR_PROPULSION
)
"""0x5371fc0f: what ArduCopter SITL reports present before its GPS is detected."""
ARDUCOPTER_ENABLED = ARDUCOPTER_PRESENT & ~(S.MAV_SYS_STATUS_GEOFENCE | S.MAV_SYS_STATUS_AHRS)
ARDUCOPTER_HEALTHY = (ARDUCOPTER_PRESENT | S.MAV_SYS_STATUS_SENSOR_PROXIMITY) & ~(
    S.MAV_SYS_STATUS_AHRS | S.MAV_SYS_STATUS_PREARM_CHECK
)
GPS = S.MAV_SYS_STATUS_SENSOR_GPS
AHRS = S.MAV_SYS_STATUS_AHRS
PREARM = S.MAV_SYS_STATUS_PREARM_CHECK

PX4_PRESENT = (
    S.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | S.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | S.MAV_SYS_STATUS_SENSOR_3D_MAG
    | S.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | GPS
    | S.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | S.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | S.MAV_SYS_STATUS_SENSOR_YAW_POSITION
    | S.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | S.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
    | S.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | AHRS
    | S.MAV_SYS_STATUS_SENSOR_BATTERY
    | PREARM
)
PX4_NEEDS_ESTIMATE = GPS | PREARM
"""PX4 health bits that turn true only with the position estimate (MAVSDK's health)."""


class BootSequence:
    """Runs one vehicle's start-up stages and reports the sensors of each."""

    def __init__(
        self,
        flight: FlightController,
        store: MissionStore,
        say: Callable[[int, str], None],
        send_home: Callable[[], None],
    ) -> None:
        self._flight = flight
        self._store = store
        self._say = say
        self._send_home = send_home
        self._booted = False
        self._home_announced = False

    def start(self, now: float) -> None:
        """(Re)boot: the mission storage holds nothing until initialisation ends."""
        self._booted = not self._flight.flavour.home_is_item_zero
        self._home_announced = not self._flight.flavour.sends_unasked
        self._store.storage_ready = self._booted

    def step(self, now: float) -> None:
        if not self._booted and self._flight.booted(now):
            self._booted = True
            self._store.storage_ready = True
            self._flight.finish_boot()
            self._say(S.MAV_SEVERITY_INFO, "ArduPilot Ready")
        if not self._home_announced and self._flight.home_set(now):
            self._home_announced = True
            self._send_home()

    def sensors(self, now: float) -> Sensors:
        flight = self._flight
        if not flight.flavour.home_is_item_zero:
            ready = flight.estimate_ready(now)
            health = PX4_PRESENT if ready else PX4_PRESENT & ~PX4_NEEDS_ESTIMATE
            return Sensors(PX4_PRESENT, PX4_PRESENT, health)
        gps = GPS if flight.position_known(now) else 0
        ahrs = AHRS if flight.uptime(now) >= flight.timeline.ahrs_s else 0
        prearm = PREARM if flight.armed or not flight.arming_failures(now) else 0
        # AC_Fence::sys_status_enabled: enabled, and an action other than report only
        acting = flight.fence_enabled and flight.params.get("FENCE_ACTION") != 0
        fence = S.MAV_SYS_STATUS_GEOFENCE if acting else 0
        breached = S.MAV_SYS_STATUS_GEOFENCE if flight.fence.breaches else 0
        return Sensors(
            ARDUCOPTER_PRESENT | gps,
            ARDUCOPTER_ENABLED | gps | ahrs | fence,
            (ARDUCOPTER_HEALTHY | gps | ahrs | prearm) & ~breached,
        )

"""When a booting vehicle gets each thing ready, and what its arming checks say until then.

The ArduCopter timeline is the one observed on ArduCopter SITL at speed-up 1 (see
docs/sitl_mock.md, "Wire facts"): "ArduPilot Ready" at 2.4 s, HEARTBEAT BOOT until
2.9 s, EKF3 at 4.4 s, a GPS fix at 10 s, the EKF origin and home at 20 s, consistent
IMUs at 23 s, AHRS healthy at 25 s and GPS in use (arming in GUIDED) at 41.5 s. Each
arming attempt fails with every check that fails at that moment, one STATUSTEXT each,
as `AP_Arming::pre_arm_checks` reports them. Tests shorten the timeline per vehicle
(`VehicleConfig.position_delay_s`, `estimate_delay_s`); every instant stays in order.
All times are simulated seconds since (re)boot: this is vehicle behaviour.
"""

from __future__ import annotations

from dataclasses import dataclass

READY_S = 2.4
BOOT_STATUS_S = 2.9
EKF_S = 4.4
GPS_FIX_S = 10.0
ORIGIN_S = 20.0
IMU_S = 23.0
AHRS_S = 25.0
ESTIMATE_S = 41.5
PREARM_PERIOD_S = 30.0
"""ArduPilot repeats its failing pre-arm checks ("PreArm: ...") every 30 s while disarmed."""


@dataclass(frozen=True)
class Timeline:
    """Seconds after boot at which each step of an autopilot's start-up is done."""

    ready_s: float
    """Initialisation done: "ArduPilot Ready", mission storage usable, arming possible."""
    boot_status_s: float
    """HEARTBEAT.system_status leaves MAV_STATE_BOOT."""
    ekf_s: float
    """An attitude estimate exists."""
    gps_fix_s: float
    """The GPS has a fix: positions are reported and its SYS_STATUS bits are set."""
    origin_s: float
    """The EKF origin and home are set (GPS_GLOBAL_ORIGIN, HOME_POSITION)."""
    imu_s: float
    """Accelerometers and gyros agree: arming in modes that need no position."""
    ahrs_s: float
    """The AHRS bits of SYS_STATUS are enabled and healthy."""
    estimate_s: float
    """The EKF uses GPS: arming and flying in modes that need a position."""

    @classmethod
    def arducopter(
        cls, position_s: float | None = None, estimate_s: float | None = None
    ) -> Timeline:
        """The observed ArduCopter start-up, with the position steps brought forward."""
        estimate = ESTIMATE_S if estimate_s is None else estimate_s
        origin = min(ORIGIN_S if position_s is None else position_s, estimate)
        imu = min(IMU_S, estimate)
        return cls(
            ready_s=READY_S,
            boot_status_s=BOOT_STATUS_S,
            ekf_s=min(EKF_S, imu),
            gps_fix_s=min(GPS_FIX_S, origin),
            origin_s=origin,
            imu_s=imu,
            ahrs_s=min(AHRS_S, estimate),
            estimate_s=estimate,
        )

    @classmethod
    def immediate(cls, estimate_s: float) -> Timeline:
        """A vehicle with no boot phase whose position arrives at `estimate_s` (PX4 here)."""
        return cls(
            ready_s=0.0,
            boot_status_s=0.0,
            ekf_s=0.0,
            gps_fix_s=estimate_s,
            origin_s=estimate_s,
            imu_s=0.0,
            ahrs_s=estimate_s,
            estimate_s=estimate_s,
        )


def arducopter_arming_failures(
    timeline: Timeline, uptime: float, needs_position: bool
) -> list[str]:
    """What ArduCopter's arming checks report at `uptime` (each becomes "Arm: <text>")."""
    if uptime < timeline.ready_s:
        return ["System not initialised"]
    if uptime < timeline.ekf_s:
        if needs_position:
            return [
                "Need Alt Estimate",
                "Accels inconsistent",
                "EKF attitude is bad",
                "AHRS: waiting for home",
            ]
        return [
            "Accels inconsistent",
            "EKF attitude is bad",
            "AHRS: not using configured AHRS type",
        ]
    failures = []
    if uptime < timeline.imu_s:
        accels_until = (timeline.ekf_s + timeline.imu_s) / 2
        failures.append("Accels inconsistent" if uptime < accels_until else "Gyros inconsistent")
    if needs_position and uptime < timeline.origin_s:
        failures.append("AHRS: waiting for home")
    elif needs_position and uptime < timeline.estimate_s:
        failures.append("Need Position Estimate")
    return failures


def arducopter_mandatory_failures(
    timeline: Timeline, uptime: float, needs_position: bool
) -> list[str]:
    """What a forced arm (param2 21196) still checks: initialised, and the position for
    modes that need one (`AP_Arming_Copter::mandatory_checks`)."""
    if uptime < timeline.ready_s:
        return ["System not initialised"]
    if needs_position and uptime < timeline.estimate_s:
        return ["Need Position Estimate"]
    return []

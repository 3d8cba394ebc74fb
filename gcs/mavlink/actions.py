"""What the ground station asks one vehicle to do: modes, arming, take-off, mission start.

The sequence is the one real ArduCopter needs from the ground: GUIDED, wait for the
position estimate (arming fails with "PreArm: ..." / "Need Position Estimate" until
then, so those failures mean "not yet" and are retried within a bound), arm, take off
at once (an idle armed copter disarms after 10 s), then AUTO and MISSION_START.
PX4 takes DO_SET_MODE with its main and sub mode in param2 and param3.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.commands import URGENT, CommandAck, CommandPolicy, send_command
from gcs.mavlink.errors import (
    CommandDeniedError,
    CommandError,
    CommandFailedError,
    CommandTemporarilyRejectedError,
    FlightError,
    GcsError,
    WaitTimeoutError,
)
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot
from gcs.mavlink.mission_protocol import MissionClient
from gcs.mavlink.mode_history import LATE_COPY_S
from gcs.mavlink.modes import custom_mode, mode_name, px4_main_sub

MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
DEFINITIVE_HINTS = ("not armable", "safety switch")
"""Arming refusals that waiting does not cure (the mode, a switch only a person can press)."""
LIFTING_MM = 300  # above home: a take-off under way
LIFT_OFF_SEEN_S = 3.0  # how long a re-sent take-off's refusal waits to see the climb


@dataclass(frozen=True)
class ReadinessPolicy:
    """Bounds of the slow steps; in wall-clock seconds."""

    arm_timeout_s: float = 90.0  # real SITL needs ~40 s for the EKF to use GPS
    arm_retry_period_s: float = 1.0
    climb_timeout_s: float = 60.0
    home_timeout_s: float = 10.0
    altitude_tolerance: float = 0.95  # "at altitude" from this fraction of the target


def is_not_ready(exc: Exception) -> bool:
    """A refusal that only means "not yet": the vehicle is still initialising.

    Real ArduCopter refuses its first arming attempts for a minute after boot with a
    changing set of reasons ("Arm: Accels inconsistent", "Arm: Gyros inconsistent",
    "Arm: AHRS: waiting for home", "PreArm: Need Position Estimate", ...), and GUIDED
    before it has a position; so every FAILED or TEMPORARILY_REJECTED answer counts as
    "not yet", within the readiness bound, unless its text says waiting cannot help."""
    if isinstance(exc, CommandTemporarilyRejectedError):
        return True
    if not isinstance(exc, CommandFailedError):
        return False
    text = exc.statustext.lower()
    return not any(hint in text for hint in DEFINITIVE_HINTS)


class FlightActions:
    """Commands for one vehicle, in its own flavour."""

    def __init__(
        self,
        link: VehicleLink,
        command_policy: CommandPolicy | None = None,
        readiness: ReadinessPolicy | None = None,
        mission: MissionClient | None = None,
    ) -> None:
        self.link = link
        self.commands = command_policy or CommandPolicy()
        self.readiness = readiness or ReadinessPolicy()
        self.mission = mission
        """The vehicle's mission client (to fly an item afresh); none: resume instead."""
        self._braked_in_mission = False
        """Held by a brake out of AUTO, which only AUTO again undoes (its HEARTBEAT may still
        say AUTO for a moment after the switch)."""
        self.first_leg_seq = 0
        """Its mission's first item after NAV_TAKEOFF and the DO_CHANGE_SPEED that follows
        it (`approach`)."""
        self.mission_speed_m_s: float | None = None
        """The speed its mission flies it at now, given again after every switch back to
        AUTO: ArduCopter forgets a DO_CHANGE_SPEED command when it enters AUTO and flies
        at WP_SPD (seen on SITL: 9.3 m/s for a 5 m/s mission after BRAKE)."""

    async def command(
        self, command: int, *params: float, policy: CommandPolicy | None = None
    ) -> CommandAck:
        return await send_command(self.link, command, *params, policy=policy or self.commands)

    async def set_mode(self, name: str, policy: CommandPolicy | None = None) -> None:
        """Switch the vehicle to mode `name`; for a moment after, a late copy of a switch
        asked for just before this one is undone (`gcs.mavlink.mode_history`)."""
        history = self.link.modes
        ask = history.begin()
        try:
            await self._switch(name, policy)
        finally:
            ended = asyncio.get_running_loop().time()
            earlier = history.end(name, ended)
        if earlier:
            self.link.spawn(self._outlast_late_copies(name, earlier, ask, ended + LATE_COPY_S))

    async def _outlast_late_copies(
        self, name: str, earlier: frozenset[str], ask: int, until: float
    ) -> None:
        """Switch to `name` again at once (a copy held up on the way comes in right behind
        the packet that overtook it) and whenever a HEARTBEAT shows one of the `earlier`
        modes, until `until` or a later switch; AUTO again forgets the speed asked for, so
        that goes again too."""
        history, loop = self.link.modes, asyncio.get_running_loop()
        with self.link.subscribe(["HEARTBEAT"]) as sub, contextlib.suppress(GcsError):
            again = True
            while history.is_latest(ask) and loop.time() < until:
                if again and history.is_latest(ask):
                    await self._switch(name, URGENT)
                    if name == "AUTO" and history.speed_m_s is not None:
                        await self.change_speed(history.speed_m_s)
                heartbeat = await sub.get(max(0.0, until - loop.time()))
                again = mode_name(int(self.link.autopilot), heartbeat.custom_mode) in earlier

    async def _switch(self, name: str, policy: CommandPolicy | None) -> None:
        autopilot = self.link.autopilot
        if autopilot == Autopilot.PX4:
            main, sub = px4_main_sub(name)
            await self.command(
                mavlink2.MAV_CMD_DO_SET_MODE, MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub,
                policy=policy,
            )  # fmt: skip
        else:
            mode = custom_mode(autopilot, name)
            await self.command(
                mavlink2.MAV_CMD_DO_SET_MODE, MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode,
                policy=policy,
            )  # fmt: skip

    async def arm(self) -> None:
        await self.command(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1)

    async def disarm(self) -> None:
        await self.command(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0)

    async def takeoff(self, altitude_m: float) -> None:
        """NAV_TAKEOFF. A re-sent one that fails because the vehicle is already lifting
        off ("already flying": the first one's ACK was lost) has done its work."""
        try:
            if self.link.autopilot == Autopilot.PX4:
                amsl = await self.home_altitude_amsl() + altitude_m
                await self.command(
                    mavlink2.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, amsl
                )
            else:
                await self.command(mavlink2.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, altitude_m)
        except (CommandFailedError, CommandDeniedError) as refused:
            if refused.attempts == 1 or not await self._lifting_off():
                raise

    async def _lifting_off(self) -> bool:
        """Whether the vehicle climbs away from the ground within a moment."""

        def climbing(msg: object) -> bool:
            return getattr(msg, "relative_alt", 0) > LIFTING_MM or getattr(msg, "vz", 0) < -10

        here = self.link.state.position
        if here is not None and here.relative_alt_m * 1000 > LIFTING_MM:
            return True
        try:
            await self.link.wait_for("GLOBAL_POSITION_INT", climbing, LIFT_OFF_SEEN_S)
        except WaitTimeoutError:
            return False
        return True

    async def home_altitude_amsl(self) -> float:
        """The home altitude (PX4 takes off to an AMSL altitude), asked for if the
        HOME_POSITION stream has not brought it yet; a guess would fly to the wrong height."""
        if self.link.state.home is None:
            with self.link.subscribe(["HOME_POSITION"]) as sub:
                with contextlib.suppress(CommandError):
                    await self.command(
                        mavlink2.MAV_CMD_REQUEST_MESSAGE, mavlink2.MAVLINK_MSG_ID_HOME_POSITION
                    )
                try:
                    await sub.next_matching(None, self.readiness.home_timeout_s)
                except WaitTimeoutError:
                    raise FlightError(
                        f"vehicle {self.link.sysid} sent no home position within "
                        f"{self.readiness.home_timeout_s:.0f} s; its take-off altitude is "
                        "relative to it"
                    ) from None
        home = self.link.state.home
        assert home is not None
        return home.alt_amsl_m

    async def arm_and_take_off(self, altitude_m: float) -> None:
        """GUIDED and armed as soon as the vehicle can (retried while it is "not ready",
        within the bound), then take off at once (an idle armed copter disarms)."""
        loop = asyncio.get_running_loop()
        bound = self.readiness.arm_timeout_s
        deadline = loop.time() + bound
        while True:
            try:
                await self.set_mode("GUIDED")
                await self.arm()
                break
            except (CommandFailedError, CommandTemporarilyRejectedError) as exc:
                if not is_not_ready(exc):
                    raise
                if loop.time() > deadline:
                    raise FlightError(
                        f"vehicle {self.link.sysid} was not ready to arm within {bound:.0f} s; "
                        f"it said last: {exc}"
                    ) from exc
            await asyncio.sleep(self.readiness.arm_retry_period_s)
        await self.takeoff(altitude_m)

    async def wait_altitude(self, altitude_m: float) -> None:
        """Until the vehicle reports at least `altitude_tolerance` of `altitude_m`."""
        target = altitude_m * self.readiness.altitude_tolerance

        def high_enough(msg: object) -> bool:
            return getattr(msg, "relative_alt", 0) / 1000.0 >= target

        position = self.link.state.position
        if position is not None and position.relative_alt_m >= target:
            return
        try:
            await self.link.wait_for(
                "GLOBAL_POSITION_INT", high_enough, self.readiness.climb_timeout_s
            )
        except WaitTimeoutError:
            alt = self.link.state.position.relative_alt_m if self.link.state.position else 0.0
            raise FlightError(
                f"vehicle {self.link.sysid} did not reach {altitude_m:.1f} m within "
                f"{self.readiness.climb_timeout_s:.0f} s (at {alt:.1f} m)"
            ) from None

    async def start_mission(self) -> None:
        """AUTO, then MISSION_START (needed from the ground, harmless in the air): at once,
        and again soon if unanswered, for the fleet starts together."""
        await self.set_mode("AUTO", URGENT)
        await self.command(mavlink2.MAV_CMD_MISSION_START, 0, 0, policy=URGENT)

    async def pause(self) -> None:
        await self._pause_or_continue(pause=True)

    async def resume(self) -> None:
        await self._pause_or_continue(pause=False)

    async def _pause_or_continue(self, pause: bool) -> None:
        """DO_PAUSE_CONTINUE; sent once more at once if the opposite one was asked for just
        before: a re-sent copy of it held up on the way comes in right behind the packet
        that overtook it (as a mode switch's does: fuzzed flights 3723, 3864), and a late
        continue would send a paused vehicle on past where the order stops it. The second
        is insurance: its answer (FAILED where ArduCopter has already reached its waypoint)
        changes nothing."""
        param = 0 if pause else 1
        await self.command(mavlink2.MAV_CMD_DO_PAUSE_CONTINUE, param, policy=URGENT)
        if self.link.modes.pause_ended(pause, asyncio.get_running_loop().time()):
            with contextlib.suppress(GcsError):
                await self.command(mavlink2.MAV_CMD_DO_PAUSE_CONTINUE, param, policy=URGENT)

    async def change_speed(self, speed_m_s: float) -> None:
        """The ground speed of the mission from here on (DO_CHANGE_SPEED, as a command)."""
        self.link.modes.speed_m_s = speed_m_s
        await self.command(mavlink2.MAV_CMD_DO_CHANGE_SPEED, 1, speed_m_s, -1, policy=URGENT)

    async def proceed(self) -> None:
        """The operator's continue after a hold: the mission goes on (`resume_mission`),
        and a vehicle held outside its mission switches back to AUTO (which resumes at
        the current item)."""
        if self._braked_in_mission or self.link.state.mode == "AUTO":
            await self.resume_mission()
        else:
            await self.back_to_mission()

    async def pause_mission(self) -> str:
        """Stop a vehicle flying its mission until `resume_mission`; says how. The mission
        is paused (DO_PAUSE_CONTINUE); ArduCopter pauses only on the way to a place, and
        where it answers FAILED ("Failed to pause": taking off, coming down, standing at
        a waypoint) the vehicle brakes instead."""
        try:
            await self.pause()
            return "mission paused"
        except (CommandFailedError, CommandDeniedError) as refused:
            braked = await self._brake()
            self._braked_in_mission = True
            return f"{braked} (the mission would not pause: {refused.statustext or refused})"

    async def brake_in_mission(self) -> str:
        """Stop a vehicle out of its mission (ArduCopter BRAKE) until `resume_mission`
        sends it on in AUTO: a new mission, or a new current item, given to a paused one
        sends it on at once."""
        braked = await self._brake()
        self._braked_in_mission = True
        return braked

    @property
    def out_of_mission(self) -> bool:
        """Stopped out of AUTO by us or found so: only AUTO again resumes its mission."""
        return self._braked_in_mission

    def found_stopped_out_of_mission(self) -> None:
        """The vehicle was stopped out of AUTO by others (a service gone, which held it
        as it stopped): only AUTO again resumes its mission."""
        self._braked_in_mission = True

    async def resume_mission(self) -> None:
        """Undo `pause_mission`: continue the paused mission, or AUTO after a brake."""
        if self._braked_in_mission:
            await self.back_to_mission()
            self._braked_in_mission = False
        else:
            await self.resume()

    async def approach(self, speed_m_s: float, speed_first: bool = False) -> None:
        """Send a vehicle stopped in its mission on at `speed_m_s`, no faster.

        ArduCopter's paused S-curve keeps the speed it was paused at, and a resume runs
        it up again whatever DO_CHANGE_SPEED asked for (SITL, paused at 5 m/s, resumed at
        1 m/s: 4.9 m/s 2 s later, 13.1 m in 6 s). Its current item flown afresh from rest
        (DO_SET_MISSION_CURRENT, acknowledged), then slowed, keeps to the speed (SITL:
        0.3 / 1.0 / 0.8 / 0.9 m/s 1, 2, 4, 6 s later, 4.2 m in 6 s;
        bench/results/approach_vs_sitl.md). The resume after it changes nothing then.
        One braked out of its mission goes back to AUTO, which flies its item afresh, and
        only then gets the speed (AUTO again would give it its mission's). PX4 resumes at
        the speed asked for.

        One still at its start (its current item NAV_TAKEOFF) is given its first leg as
        its current item first: from NAV_TAKEOFF its mission would run the DO_CHANGE_SPEED
        after it and fly on at cruise speed (random scatter of 8 UAVs at 10 m/s, on the mock
        and on SITL: uav6, held out of its mission 7 m short of its limit, sped up to 3 m/s
        on its approach, stopped 1.7 m inside its encounter and took the lead; uav1 then
        waited out its landing, and the flight took 1.24x its timing).

        `speed_first`: the speed goes before the item is made current, so that the
        vehicle sets off no faster should the link fall silent between the two (SITL:
        at most 1.04 m/s for 1 m/s from a standstill, where the item first surged to
        4.5 m/s); slower, so only where the room is short (`Gatekeeper._speed_first`).
        Not for one braked out of its mission: ArduCopter takes no speed in BRAKE, and
        AUTO forgets one."""
        seq = self.link.state.mission_seq
        item = max(seq, self.first_leg_seq)
        mission = self.mission if self.link.autopilot == Autopilot.ARDUPILOT else None
        if self._braked_in_mission:
            if mission is not None and item != seq:
                await mission.set_current(item)  # out of AUTO: only the next item
            await self.set_mode("AUTO", URGENT)
            self._braked_in_mission = False
            await self.change_speed(speed_m_s)
            return
        if speed_first:
            await self.change_speed(speed_m_s)
        if mission is not None:
            await mission.set_current(item)
        if not speed_first:
            await self.change_speed(speed_m_s)
        await self.resume()

    async def back_to_mission(self) -> None:
        """AUTO again (the current item restarts), at the mission's speed."""
        await self.set_mode("AUTO", URGENT)
        if self.mission_speed_m_s is not None:
            await self.change_speed(self.mission_speed_m_s)

    async def return_to_launch(self) -> None:
        await self.set_mode("RTL", URGENT)

    async def land(self) -> None:
        await self.set_mode("LAND", URGENT)

    async def hold(self, in_mission: bool = False) -> str:
        """The operator's hold: stop where it is, in whatever it is doing; says how.

        In a mission (AUTO, or `in_mission`: just told to start one, which its HEARTBEAT
        may not show yet), `pause_mission`; otherwise the vehicle brakes to a hover
        (ArduCopter BRAKE, PX4 AUTO.LOITER). A vehicle disarmed on the ground is left
        alone; one armed on the ground (about to take off), or sent an ARM it has not told
        of yet, is disarmed, which autopilots refuse in the air (a stale "on the ground"
        cannot drop a flying vehicle): one they refuse brakes."""
        state = self.link.state
        if state.down:
            return "on the ground, disarmed: nothing to hold"
        if (state.armed or state.arm_unconfirmed) and not state.airborne:
            with contextlib.suppress(CommandFailedError, CommandDeniedError):
                await self.disarm()
                return "on the ground: disarmed"
        if in_mission or state.mode == "AUTO":
            return await self.pause_mission()
        return await self._brake()

    async def _brake(self) -> str:
        mode = "GUIDED" if self.link.autopilot == Autopilot.PX4 else "BRAKE"
        await self.set_mode(mode, URGENT)
        return f"holding in {mode if mode == 'BRAKE' else 'LOITER'}"

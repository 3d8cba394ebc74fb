"""Commands and their typed errors against simulated vehicles, on the virtual clock: the
vehicles in memory and the ground station's timeouts and retries on the one clock, so a
vehicle's minute of boot is simulated, not waited for. Commands over real sockets are the
conformance tests'."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.actions import FlightActions, ReadinessPolicy, is_not_ready
from gcs.mavlink.commands import CommandPolicy, send_command
from gcs.mavlink.errors import (
    CommandFailedError,
    CommandTimeoutError,
    CommandUnsupportedError,
    FlightError,
)
from gcs.mavlink.mission_item import Autopilot
from gcs.mavlink.modes import custom_mode
from gcs.mavlink.vehicle_state import MAV_STATE_BOOT
from sitl_mock import Simulator, VehicleConfig
from tests.inprocess.service import until

from .conftest import CMAC

pytestmark = [pytest.mark.virtual_clock]


async def wait_for_estimate(sim: Simulator, sysid: int = 1) -> None:
    await until(lambda: sim.state(sysid).estimate_ready, 100.0, "the position estimate")


def slow_estimate(sysid: int = 1, autopilot: str = "ardupilot", seconds: float = 600.0):
    return VehicleConfig(sysid=sysid, home=CMAC, autopilot=autopilot, estimate_delay_s=seconds)


async def test_arming_before_the_position_estimate_fails_with_the_prearm_text(simulator, links):
    sim = await simulator([slow_estimate()])
    link = await links(sim, 1)
    await link.wait_for("HEARTBEAT", lambda hb: hb.system_status != MAV_STATE_BOOT, 10.0)
    with pytest.raises(CommandFailedError, match="Arm: ") as caught:
        await FlightActions(link).arm()
    assert caught.value.command == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM
    assert is_not_ready(caught.value)  # ArduCopter's early refusals all mean "not yet"


async def test_a_vehicle_never_ready_is_reported_with_what_it_said_last(simulator, links):
    """Real ArduCopter refuses with several changing texts for a minute after boot; the
    bound ends the wait and the error says what the vehicle said last."""
    sim = await simulator([slow_estimate()])
    link = await links(sim, 1)
    patience = ReadinessPolicy(arm_timeout_s=60.0, arm_retry_period_s=0.1)
    with pytest.raises(FlightError, match="not ready to arm within 60 s") as caught:
        await FlightActions(link, readiness=patience).arm_and_take_off(5.0)
    assert "Need Position Estimate" in str(caught.value)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
async def test_arming_waits_for_the_estimate_then_takes_off(simulator, links, autopilot: str):
    sim = await simulator([slow_estimate(autopilot=autopilot, seconds=20.0)])
    link = await links(sim, 1)
    actions = FlightActions(link, readiness=ReadinessPolicy(arm_retry_period_s=0.1))
    await actions.arm_and_take_off(5.0)
    await actions.wait_altitude(5.0)
    assert sim.state(1).armed and sim.state(1).alt > 4.5


async def test_px4_takes_off_to_the_asked_height_before_its_home_position_arrived(
    simulator, links
) -> None:
    """PX4's take-off altitude is AMSL: without the home altitude the GCS must ask for it,
    not guess 0 m (which sent the vehicle nowhere until it disarmed itself)."""
    sim = await simulator([VehicleConfig(sysid=1, home=CMAC, autopilot="px4")])
    link = await links(sim, 1)
    await wait_for_estimate(sim)
    actions = FlightActions(link, readiness=ReadinessPolicy(arm_retry_period_s=0.1))
    await actions.set_mode("GUIDED")
    await actions.arm()
    link.state.home = None  # as if the 0.5 Hz HOME_POSITION stream had not come yet
    await actions.takeoff(5.0)
    await actions.wait_altitude(5.0)
    assert sim.state(1).alt == pytest.approx(5.0, abs=0.6)


async def test_arming_in_auto_is_refused_at_once(simulator, links) -> None:
    sim = await simulator([VehicleConfig(sysid=1, home=CMAC)])
    link = await links(sim, 1)
    await wait_for_estimate(sim)
    actions = FlightActions(link, readiness=ReadinessPolicy(arm_timeout_s=30.0))
    await actions.set_mode("AUTO")
    with pytest.raises(CommandFailedError) as caught:
        await actions.arm()
    assert not is_not_ready(caught.value)  # definitive: nobody waits 30 s for it


async def test_unknown_commands_are_unsupported(simulator, links) -> None:
    sim = await simulator([VehicleConfig(sysid=1, home=CMAC)])
    link = await links(sim, 1)
    with pytest.raises(CommandUnsupportedError, match="WAYPOINT_USER_1 UNSUPPORTED"):
        await send_command(link, 31000)


async def test_takeoff_while_disarmed_fails(simulator, links) -> None:
    sim = await simulator([VehicleConfig(sysid=1, home=CMAC)])
    link = await links(sim, 1)
    await wait_for_estimate(sim)
    actions = FlightActions(link)
    await actions.set_mode("GUIDED")
    with pytest.raises(CommandFailedError, match="NAV_TAKEOFF"):
        await actions.takeoff(10.0)


async def test_an_unanswered_command_times_out_after_its_retries(simulator, links) -> None:
    sim = await simulator([VehicleConfig(sysid=1, home=CMAC)])
    link = await links(sim, 1)
    sim.silence(1, seconds=100.0)
    policy = CommandPolicy(timeout_s=0.1, retries=2)
    with pytest.raises(CommandTimeoutError, match="not acknowledged after 3 attempts"):
        await send_command(link, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1, policy=policy)


@pytest.mark.parametrize("mode", ["LOITER", "RTL", "LAND", "AUTO"])
async def test_px4_modes_are_set_with_main_and_sub_mode(simulator, links, mode: str) -> None:
    sim = await simulator([VehicleConfig(sysid=1, home=CMAC, autopilot="px4")])
    link = await links(sim, 1)
    await wait_for_estimate(sim)
    await FlightActions(link).set_mode(mode)
    assert sim.state(1).custom_mode == custom_mode(Autopilot.PX4, mode)

"""The passing order's commands to one vehicle against the operator's (gcs.fleet.gatekeeper):
an approach under way must not land after the operator's hold and undo it.

Fuzzed flight 2079 found it (tests/fuzz/test_regressions.py): the order had just sent a
vehicle its approach speed and was about to resume it when the operator held the fleet;
on a slow link the resume went out after the hold's pause, and the vehicle flew on while
held. Here the vehicle's link is a recorder whose first command is slow, on the event
loop, so that the race happens every time."""

from __future__ import annotations

import asyncio
from typing import cast

from gcs.fleet.gatekeeper import GateCommander
from gcs.mavlink.actions import FlightActions
from gcs.mavlink.errors import CommandTimeoutError
from gcs.mission.motion import Gate, StoppingRule


class SlowLink:
    """What a vehicle was sent, in order; the first command waits for `released`."""

    def __init__(self) -> None:
        self.sent: list[str] = []
        self.released = asyncio.Event()
        self.out_of_mission = False  # braked: only AUTO again (resume_mission) sends it on

    async def _send(self, what: str) -> None:
        if not self.sent:
            await self.released.wait()
        self.sent.append(what)

    async def change_speed(self, speed_m_s: float) -> None:
        await self._send(f"speed {speed_m_s:g}")

    async def resume_mission(self) -> None:
        await self._send("resume")
        self.out_of_mission = False

    async def approach(self, speed_m_s: float, speed_first: bool = False) -> None:
        await self.change_speed(speed_m_s)
        await self.resume_mission()

    async def pause_mission(self) -> str:
        await self._send("pause")
        return "mission paused"

    async def brake_in_mission(self) -> str:
        await self._send("brake")
        self.out_of_mission = True
        return "holding in BRAKE"


async def test_the_operators_hold_is_not_undone_by_an_approach_under_way() -> None:
    link = SlowLink()
    failures: list[str] = []
    commander = GateCommander(
        {"uav1": cast(FlightActions, link)},
        StoppingRule(),
        cruise=lambda uav: 5.0,
        on_failure=lambda uav, why: failures.append(why),
    )
    commander.found_stopped("uav1")  # stopped by the order, waiting for another
    commander.want("uav1", Gate.CREEP, 1.0)  # the way opens: approach at 1 m/s
    await asyncio.sleep(0)  # its speed is on the way, slowly

    await commander.stand_down(["uav1"])  # the operator holds it ...
    hold = asyncio.ensure_future(link.pause_mission())  # ... and pauses it
    link.released.set()
    await hold
    for _ in range(10):  # anything the order still had to send has gone by now
        await asyncio.sleep(0)
    commander.settle("uav1", Gate.STOP)

    assert link.sent == ["pause"], link.sent
    assert failures == []
    await commander.close()


class Recorder:
    """What a vehicle was sent, in order, each answered at once."""

    def __init__(self) -> None:
        self.sent: list[str] = []
        self.out_of_mission = False

    async def pause_mission(self) -> str:
        self.sent.append("pause")
        return "mission paused"

    async def brake_in_mission(self) -> str:
        self.sent.append("brake")
        self.out_of_mission = True
        return "holding in BRAKE"

    async def change_speed(self, speed_m_s: float) -> None:
        self.sent.append(f"speed {speed_m_s:g}")

    async def resume_mission(self) -> None:
        self.sent.append("resume")
        self.out_of_mission = False

    async def approach(self, speed_m_s: float, speed_first: bool = False) -> None:
        await self.change_speed(speed_m_s)
        await self.resume_mission()


def commanding(link: object) -> GateCommander:
    return GateCommander(
        {"uav1": cast(FlightActions, link)},
        StoppingRule(),
        cruise=lambda uav: 5.0,
        on_failure=lambda uav, why: None,
    )


def recorded() -> tuple[GateCommander, Recorder]:
    link = Recorder()
    return commanding(link), link


async def settled(commander: GateCommander) -> None:
    for _ in range(10):
        await asyncio.sleep(0)


async def test_a_vehicle_braked_for_a_replan_goes_on_in_its_mission() -> None:
    """Braked out of its mission (its mission changes meanwhile, which a pause would not
    survive), it goes on with `resume_mission` (AUTO again), not with a speed change."""
    commander, link = recorded()
    commander.found_stopped("uav1")
    commander.brake("uav1")
    await settled(commander)
    assert link.sent == ["brake"]
    commander.want("uav1", Gate.GO)
    await settled(commander)
    assert link.sent == ["brake", "resume"]
    await commander.close()


async def test_a_brake_asked_for_while_a_pause_is_under_way_still_brakes() -> None:
    """The order pauses a vehicle over a slow link; a live replan asks for a brake before
    the pause is answered. The pause's end is not the brake: the new mission would give
    the pause up and send the vehicle on (fuzzed flight 4703: 0.63 m)."""
    link = SlowLink()
    commander = commanding(link)
    commander.want("uav1", Gate.STOP)  # the pause, slowly
    await asyncio.sleep(0)
    commander.brake("uav1")  # the replan's
    link.released.set()
    await settled(commander)
    assert link.sent == ["pause", "brake"], link.sent
    await commander.close()


class SilentThenHeard(Recorder):
    """A vehicle whose first pause goes unanswered (its link silent), the rest answered."""

    async def pause_mission(self) -> str:
        if "lost" not in self.sent:
            self.sent.append("lost")
            raise CommandTimeoutError(1, 193, None, detail="not answered")
        return await super().pause_mission()


async def test_a_change_the_vehicle_did_not_answer_is_tried_again_once_it_is_heard() -> None:
    """Fuzzed flight 1014 with uav4's link silent 5 s: the pause decided while nobody
    heard it went unanswered; the gate was taken as in force, and the vehicle, heard
    again, flew on past its limit to 2.32 m from another."""
    link = SilentThenHeard()
    commander = commanding(link)
    commander.want("uav1", Gate.STOP)
    await settled(commander)
    assert link.sent == ["lost"]
    commander.heard("uav1")
    await settled(commander)
    assert link.sent == ["lost", "pause"]
    commander.heard("uav1")  # heard again: nothing more to do
    await settled(commander)
    assert link.sent == ["lost", "pause"]
    await commander.close()


async def test_an_approach_sped_up_is_sent_its_new_speed_without_a_stop() -> None:
    """Approaching its limit at 1 m/s, the vehicle is wanted faster (the limit moved on
    with its leader): one speed command, no pause and no resume."""
    commander, link = recorded()
    commander.found_stopped("uav1")
    commander.want("uav1", Gate.CREEP, 1.0)
    await settled(commander)
    assert link.sent == ["speed 1", "resume"]
    commander.want("uav1", Gate.CREEP, 3.0)
    await settled(commander)
    assert link.sent == ["speed 1", "resume", "speed 3"]
    commander.want("uav1", Gate.CREEP, 3.0)  # the same again: nothing to send
    await settled(commander)
    assert link.sent == ["speed 1", "resume", "speed 3"]
    await commander.close()


async def test_an_approach_is_sent_its_speed_again_at_each_item_its_mission_reaches() -> None:
    """A DO_CHANGE_SPEED item of the mission sets the next leg's speed whatever the
    approach asked for: at each item reached, an approaching vehicle is given its speed
    again (and nothing else); one flying on, or stopped, is sent nothing."""
    commander, link = recorded()
    commander.found_stopped("uav1")
    commander.want("uav1", Gate.CREEP, 0.5)
    await settled(commander)
    assert link.sent == ["speed 0.5", "resume"]
    commander.item_reached("uav1")
    await settled(commander)
    assert link.sent == ["speed 0.5", "resume", "speed 0.5"]
    commander.want("uav1", Gate.STOP)
    await settled(commander)
    commander.item_reached("uav1")
    await settled(commander)
    assert link.sent == ["speed 0.5", "resume", "speed 0.5", "pause"]
    await commander.close()

"""Following a flight again from where its vehicles are (after a restart or a takeover).

Nobody kept the passing order for a while, so nothing is taken on trust: every vehicle
still in the plan is first stopped (its mission paused, or braked where ArduCopter will
not pause; one already held out of AUTO, as a stopping service leaves it, stays so) and
is then let go by the passing order, as the follower decides from where each vehicle is
found along its path. A vehicle landing or going home has left the plan; one on the
ground at its goal has finished, and one on the ground elsewhere is out of the way.
"""

from __future__ import annotations

from gcs.fleet.crew import Crew, Fallback
from gcs.fleet.events import Withdrawn
from gcs.fleet.member import Member
from gcs.fleet.outcome import VehicleOutcome
from gcs.mission.motion import Gate

LEFT_THE_PLAN = {
    "LAND": Fallback.LAND,
    "RTL": Fallback.RTL,
    "SMART_RTL": Fallback.RTL,
    "AUTO.LAND": Fallback.LAND,
    "AUTO.RTL": Fallback.RTL,
}
"""Modes in which a vehicle found in the air has left the plan, and what it does."""


async def resume(crew: Crew) -> dict[str, VehicleOutcome[str]]:
    """Take every vehicle up where it is and stop those still in the plan; the follower
    (`Follower.follow`) then lets them go in the passing order. Says how each stopped."""
    in_plan = []
    for uav, member in crew.members.items():
        _find(crew, member)
        state = member.link.state
        left = LEFT_THE_PLAN.get(state.mode)
        if state.down:
            if not member.tracker.landing(state):
                _withdraw(crew, uav, Fallback.LAND)  # down short of its goal
        elif left is not None:
            _withdraw(crew, uav, left)
        else:
            in_plan.append(uav)
    outcomes = await crew.each(_stop, "resume", in_plan)
    for uav in in_plan:
        crew.commander.found_stopped(uav)
        crew.gatekeeper.gates[uav] = Gate.STOP
    crew.ready = crew.started = True
    return outcomes


def _find(crew: Crew, member: Member) -> None:
    """Where the vehicle is on its plan and along its path, by its current item."""
    state = member.link.state
    member.tracker.find(state)
    places = crew.flight.places(member.uav_id)
    passed, ahead = member.tracker.places(state)
    lo = places[passed.seq] if passed else 0.0
    hi = places[ahead.seq] if ahead else crew.flight.paths[member.uav_id].length
    member.along.find(state, lo, max(lo, hi))


def _withdraw(crew: Crew, uav: str, fallback: Fallback) -> None:
    crew.withdrawn[uav] = fallback.value
    crew.bus.publish(Withdrawn(uav, fallback.value))


async def _stop(member: Member) -> str:
    if member.link.state.mode == "AUTO":
        return await member.actions.pause_mission()
    member.actions.found_stopped_out_of_mission()
    return f"held in {member.link.state.mode}"

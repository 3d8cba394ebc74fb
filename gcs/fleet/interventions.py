"""What the operator (or a failure) does to a flight: hold, continue, withdraw, abort.

These are the commands that must always work. Each acts on the vehicles at once and
answers per vehicle; none waits for the flight's other work.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable, Iterable

from gcs.fleet.crew import Crew, Fallback
from gcs.fleet.events import Aborted, OperatorContinued, OperatorHeld, Withdrawn
from gcs.fleet.member import Member
from gcs.fleet.outcome import VehicleOutcome
from gcs.mission.motion import Gate


async def hold(crew: Crew, uav_ids: Iterable[str] | None = None) -> dict[str, VehicleOutcome[str]]:
    """The operator's hold: the vehicles stop where they are until the operator continues
    them (nothing else does: the passing order leaves a held vehicle alone)."""
    chosen = set(crew.members if uav_ids is None else uav_ids)
    crew.held |= chosen
    crew.bus.publish(OperatorHeld(tuple(sorted(chosen))))
    await crew.commander.stand_down(chosen)
    outcomes = await crew.each(lambda m: m.actions.hold(crew.started), "hold", chosen)
    for uav in chosen:
        crew.commander.settle(uav, Gate.STOP)
        crew.gatekeeper.gates[uav] = Gate.STOP
    return outcomes


async def continue_(
    crew: Crew, uav_ids: Iterable[str] | None = None
) -> dict[str, VehicleOutcome[None]]:
    """Lift the operator's hold: a vehicle flies on unless the passing order has it wait
    for another (then it goes on as soon as that one has passed). One the operator had
    sent down or home goes on with that (`_leaving`). One not held is left to the passing
    order: taking it for stopped once left a creeping vehicle going on through the place
    it had to stop short of (fuzzed flight 3095, 3.13 m apart)."""
    asked = set(crew.members if uav_ids is None else uav_ids)
    chosen = asked - set(crew.withdrawn)
    leaving = await _leaving(crew, asked & set(crew.withdrawn), every=uav_ids is None)
    held = chosen & crew.held
    crew.held -= chosen
    crew.bus.publish(OperatorContinued(tuple(sorted(chosen))))
    along = {uav: m.along for uav, m in crew.members.items()}
    crew.gatekeeper.decide(along, held)
    gates, waits = crew.gatekeeper.gates, crew.gatekeeper.waits_for
    moving = {uav for uav in held if gates[uav] == Gate.GO}
    outcomes = await crew.each(lambda m: m.actions.proceed(), "continue", moving)
    for uav in moving:
        crew.commander.settle(uav, Gate.GO)
    for uav in held - moving:  # stopped for now; the order lets it go when it may
        crew.gatekeeper.gates[uav] = Gate.STOP
    waiting: dict[str, VehicleOutcome[None]] = {
        uav: VehicleOutcome(uav, True, f"waits for {waits[uav]} to pass first")
        for uav in held - moving
    }
    free: dict[str, VehicleOutcome[None]] = {
        uav: VehicleOutcome(uav, True, "not held: it flies by the passing order")
        for uav in chosen - held
    }
    return {**outcomes, **waiting, **free, **leaving}


async def _leaving(crew: Crew, withdrawn: set[str], every: bool) -> dict[str, VehicleOutcome[None]]:
    """Vehicles the operator sent down or home and then held go on landing or returning
    (their command again); one not held is already doing that (and a continue of the
    whole fleet leaves it out)."""
    held = withdrawn & crew.held
    crew.held -= held
    outcomes: dict[str, VehicleOutcome[None]] = {}
    for mode in sorted({crew.withdrawn[uav] for uav in held}):
        going = [uav for uav in sorted(held) if crew.withdrawn[uav] == mode]
        outcomes |= await fall_back(crew, going, Fallback(mode))
    if not every:
        for uav in withdrawn - held:
            mode = crew.withdrawn[uav]
            outcomes[uav] = VehicleOutcome(
                uav, True, f"already on its way ({mode}): out of the plan"
            )
    return outcomes


async def withdraw(crew: Crew, uav_id: str, mode: str) -> VehicleOutcome[None]:
    """One vehicle lands or returns home on the operator's word and leaves the plan."""
    fallback = Fallback(mode)
    crew.withdrawn[uav_id] = fallback.value
    crew.held.discard(uav_id)
    crew.bus.publish(Withdrawn(uav_id, fallback.value))
    outcomes = await fall_back(crew, [uav_id], fallback)
    return outcomes[uav_id]


async def abort(
    crew: Crew, mode: str = "rtl", reason: str = "aborted by the operator"
) -> dict[str, VehicleOutcome[None]]:
    """Every vehicle to RTL or LAND at once; the flight then ends."""
    fallback = Fallback(mode)
    crew.aborted = reason
    crew.bus.publish(Aborted(fallback.value, reason))
    return await fall_back(crew, list(crew.members), fallback)


async def fall_back(
    crew: Crew, uav_ids: Iterable[str], fallback: Fallback
) -> dict[str, VehicleOutcome[None]]:
    chosen = list(uav_ids)
    await crew.commander.stand_down(chosen)
    if fallback == Fallback.HOLD:
        outcomes = await crew.each(lambda m: m.actions.hold(crew.started), "hold", chosen)
        return {uav: VehicleOutcome(uav, o.ok, o.detail) for uav, o in outcomes.items()}
    action: Callable[[Member], Awaitable[None]] = (
        (lambda m: m.actions.land())
        if fallback == Fallback.LAND
        else (lambda m: m.actions.return_to_launch())
    )
    return await crew.each(action, fallback.value, chosen)

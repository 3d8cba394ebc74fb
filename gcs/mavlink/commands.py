"""COMMAND_LONG / COMMAND_INT with COMMAND_ACK handling, as the MAVLink command protocol says.

A command is re-sent when its ACK does not come, with `confirmation` counting the
attempts; IN_PROGRESS extends the wait without re-sending; any other result ends in
a typed error that carries every STATUSTEXT the vehicle sent with that attempt (real
ArduCopter explains one refused arming with several: "Arm: Accels inconsistent",
"Arm: Gyros inconsistent", ...). Command numbers are pymavlink's `MAV_CMD_*`.
"""

from __future__ import annotations

import asyncio
import contextlib
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.errors import CommandTimeoutError, GcsError, WaitTimeoutError, command_error
from gcs.mavlink.link import CommandTurn, VehicleLink
from gcs.mavlink.subscription import Subscription

STATUSTEXT_GRACE_S = 0.15  # a failure's explanation may trail its ACK


@dataclass(frozen=True)
class CommandPolicy:
    """How long to wait for an ACK and how often to re-send (failure mode 1: settable)."""

    timeout_s: float = 1.5
    retries: int = 7
    """Re-sends after the first: with 20 % loss each way, a try is lost 36 % of the time
    and eight in a row 0.03 % (four in a row were 1.7 %: one start in a few failed)."""
    in_progress_timeout_s: float = 30.0


URGENT = CommandPolicy(timeout_s=0.2, retries=15)
"""The operator's and the passing order's commands in flight (pause, brake, continue,
land, return home, speed, current item): sent again soon when no answer comes, for a lost
packet must not cost a vehicle metres at speed nor the operator a second; each is
harmless twice."""


@dataclass(frozen=True)
class CommandAck:
    command: int
    result: int
    attempts: int
    statustext: str = ""


Params = tuple[float, float, float, float, float, float, float]


def _params(values: tuple[float, ...]) -> Params:
    padded = tuple(float(v) for v in values) + (0.0,) * (7 - len(values))
    return padded[:7]  # type: ignore[return-value]


async def send_command(
    link: VehicleLink,
    command: int,
    *params: float,
    policy: CommandPolicy | None = None,
) -> CommandAck:
    """Send COMMAND_LONG and return its ACCEPTED ACK, or raise the typed error."""
    p = _params(params)

    def encode(confirmation: int) -> Any:
        return link.codec.command_long_encode(link.sysid, link.compid, command, confirmation, *p)

    return await _exchange(link, command, encode, policy or CommandPolicy())


async def send_command_int(
    link: VehicleLink,
    command: int,
    *params: float,
    lat_e7: int = 0,
    lon_e7: int = 0,
    alt: float = 0.0,
    frame: int = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    policy: CommandPolicy | None = None,
) -> CommandAck:
    """COMMAND_INT, for commands with a position (it has no confirmation field)."""
    p = _params(params)

    def encode(confirmation: int) -> Any:
        return link.codec.command_int_encode(
            link.sysid, link.compid, frame, command, 0, 0, *p[:4], lat_e7, lon_e7, alt
        )

    return await _exchange(link, command, encode, policy or CommandPolicy())


async def _exchange(
    link: VehicleLink, command: int, encode: Any, policy: CommandPolicy
) -> CommandAck:
    """One command's attempts, alone on the link among commands of its number, which
    wait until the answers to its earlier attempts are in too (they can come after the
    one that ended it: the ACK of a re-sent attempt). A COMMAND_ACK names only the
    command's number, so an answer left on the wire would end the next command of that
    number (seen: the late ACK of an operator's re-sent RTL taken for the abort's LAND,
    which was lost and never sent again). Other commands go at once, and so does the
    caller: the late answers are awaited apart from it. A command its caller gave up on
    before any answer came leaves the answers still owed when that wait runs out to the
    next command of the number, which takes them as not its own (`_Tally`)."""
    turn = link.command_turn(command)
    await turn.lock.acquire()
    tally = _Tally(skip=turn.take_owed(asyncio.get_running_loop().time()))
    sub = link.subscribe(["COMMAND_ACK", "STATUSTEXT"])
    try:
        link.ensure_up()  # a vehicle not heard lately: fail now, do not wait out every retry
        return await _attempts(link, sub, command, encode, policy, tally)
    except asyncio.CancelledError:
        tally.given_up = not tally.answered
        raise
    finally:
        if tally.answered < tally.sent and not link.closed:
            link.spawn(_late_answers(sub, command, tally, policy.timeout_s, turn))
        else:
            sub.close()
            turn.lock.release()


OWED_FOR_S = 5.0
"""How long an answer given up on may still come: a link's delay, not a vehicle's."""


@dataclass
class _Tally:
    """Attempts sent and final answers received (an IN_PROGRESS is not one), and the
    answers to skip first: owed to an earlier command of the number, given up on by its
    caller before any answer came, whose wait for them ran out (fuzzed flight 14852: a
    pause, lost, took the late ACK of the continue it had cancelled for its own; the
    vehicle crept on through the fleet's hold, 3.04 m from another). Skipping one that
    was this command's own costs a re-send, so the answers owed to attempts a later
    one's answer ended are not carried: under 20 % loss most of them are lost, and the
    re-sends they cost held brakes up by 0.2 s at 10 m/s (fuzzed flight 15490, 0.44 m)."""

    sent: int = 0
    answered: int = 0
    last_sent: float = 0.0
    skip: int = 0
    given_up: bool = False


async def _attempts(
    link: VehicleLink, sub: Any, command: int, encode: Any, policy: CommandPolicy, tally: _Tally
) -> CommandAck:
    for attempt in range(policy.retries + 1):
        texts: list[str] = []  # what the vehicle said about this attempt
        link.send(encode(attempt))
        tally.sent, tally.last_sent = tally.sent + 1, asyncio.get_running_loop().time()
        try:
            ack = await _await_ack(sub, command, policy.timeout_s, texts, tally)
        except WaitTimeoutError:
            continue
        if ack.result == mavlink2.MAV_RESULT_IN_PROGRESS:
            ack = await _await_final_ack(link, sub, command, policy, texts, tally)
        if ack.result == mavlink2.MAV_RESULT_ACCEPTED:
            return CommandAck(command, ack.result, attempt + 1, "; ".join(texts))
        await _collect_trailing_texts(sub, texts)
        error = command_error(link.sysid, command, ack.result, "; ".join(texts))
        error.attempts = attempt + 1
        raise error
    raise CommandTimeoutError(
        link.sysid,
        command,
        None,
        "",
        detail=f"not acknowledged after {policy.retries + 1} attempts of {policy.timeout_s:.2f} s",
    )


async def _await_ack(
    sub: Any, command: int, timeout: float, texts: list[str], tally: _Tally
) -> Any:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while True:
        msg = await sub.get(max(0.0, deadline - loop.time()))
        if msg.get_type() == "STATUSTEXT":
            texts.append(_text(msg))
        elif msg.command == command:
            final = msg.result != mavlink2.MAV_RESULT_IN_PROGRESS
            if final and tally.skip:
                tally.skip -= 1  # an earlier command's
                continue
            tally.answered += final
            return msg


async def _await_final_ack(
    link: VehicleLink,
    sub: Any,
    command: int,
    policy: CommandPolicy,
    texts: list[str],
    tally: _Tally,
) -> Any:
    """After IN_PROGRESS: wait (without re-sending) for the ACK that ends the command."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + policy.in_progress_timeout_s
    try:
        while True:
            ack = await _await_ack(sub, command, max(0.0, deadline - loop.time()), texts, tally)
            if ack.result != mavlink2.MAV_RESULT_IN_PROGRESS:
                return ack
    except WaitTimeoutError:
        raise CommandTimeoutError(
            link.sysid,
            command,
            mavlink2.MAV_RESULT_IN_PROGRESS,
            "; ".join(texts),
            detail=f"still in progress after {policy.in_progress_timeout_s:.1f} s",
        ) from None


async def _late_answers(
    sub: Subscription, command: int, tally: _Tally, timeout_s: float, turn: CommandTurn
) -> None:
    """Take the answers still owed to earlier attempts, until the last attempt's timeout
    (one lost on the way is not waited for longer), then let the next command go, telling
    it how many may still come."""
    deadline = tally.last_sent + timeout_s
    loop = asyncio.get_running_loop()
    try:
        with contextlib.suppress(GcsError):
            while tally.answered < tally.sent and loop.time() < deadline:
                await _await_ack(sub, command, deadline - loop.time(), [], tally)
    finally:
        sub.close()
        turn.owed = tally.sent - tally.answered + tally.skip if tally.given_up else 0
        turn.owed_until = loop.time() + OWED_FOR_S
        turn.lock.release()


async def _collect_trailing_texts(sub: Any, texts: list[str]) -> None:
    """The rest of a refusal's reasons, if the vehicle sends some right after the ACK."""
    deadline = asyncio.get_running_loop().time() + STATUSTEXT_GRACE_S
    with contextlib.suppress(WaitTimeoutError):
        while True:
            msg = await sub.next_matching(_is_text, deadline - asyncio.get_running_loop().time())
            texts.append(_text(msg))


def _is_text(msg: Any) -> bool:
    return bool(msg.get_type() == "STATUSTEXT")


def _text(msg: Any) -> str:
    text = msg.text if isinstance(msg.text, str) else bytes(msg.text).decode(errors="replace")
    return text.rstrip("\x00")

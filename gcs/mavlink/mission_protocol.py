"""The MAVLink mission protocol, client side: upload, download, clear, set current.

Set current is the acknowledged DO_SET_MISSION_CURRENT command where the autopilot has
it (`set_current`). Retries follow the spec and QGroundControl (settable, failure mode
1): MISSION_COUNT is re-sent after `step_timeout_s`, at most `retries` times; the
openings that change nothing when repeated (MISSION_REQUEST_LIST, MISSION_CLEAR_ALL, and
MISSION_SET_CURRENT where the command is missing) are re-sent every `item_timeout_s`
within the same overall bound. While items flow the exchange is nudged every
`item_timeout_s` (upload: the last item again, which also recovers a lost final ACK;
download: the request again) and fails only when no new item has moved for
`step_timeout_s * (retries + 1)`, so a noisy link is slow but not fatal. An upload that
timed out or was refused for a passing reason (ERROR, CANCELLED) is started again from
MISSION_COUNT, `whole_transfer_attempts` in all, while the vehicle is still heard. Every
wait is bounded; a definitive refusal is never retried; a link loss or reboot ends the
exchange at once with its own error.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink import ardupilot
from gcs.mavlink.commands import URGENT, send_command
from gcs.mavlink.errors import (
    CommandUnsupportedError,
    MissionMismatchError,
    MissionRejectedError,
    MissionResult,
    MissionTimeoutError,
    MissionTransferError,
    NoSpaceError,
    WaitTimeoutError,
    mission_error,
)
from gcs.mavlink.link import VehicleLink
from gcs.mavlink.mission_item import Autopilot, Mission, MissionItem
from gcs.mavlink.subscription import Subscription
from gcs.mavlink.vehicle_state import MAV_STATE_BOOT

MISSION_TYPE_MISSION = mavlink2.MAV_MISSION_TYPE_MISSION
MISSION_TYPE_FENCE = mavlink2.MAV_MISSION_TYPE_FENCE
MISSION_TYPE_RALLY = mavlink2.MAV_MISSION_TYPE_RALLY
TYPE_NAMES = {
    MISSION_TYPE_MISSION: "mission",
    MISSION_TYPE_FENCE: "fence",
    MISSION_TYPE_RALLY: "rally",
}
REQUESTS = ("MISSION_REQUEST", "MISSION_REQUEST_INT")  # real ArduPilot asks with 40
BOOT_WAITS = 3  # NO_SPACE answers taken for "still booting" before one is believed


@dataclass(frozen=True)
class TransferPolicy:
    step_timeout_s: float = 1.5
    item_timeout_s: float = 0.25
    retries: int = 5
    whole_transfer_attempts: int = 3  # after a timeout or a passing refusal

    @property
    def stall_limit_s(self) -> float:
        return self.step_timeout_s * (self.retries + 1)


@dataclass(frozen=True)
class UploadResult:
    sysid: int
    items: int
    seconds: float
    resends: int
    verified: bool


class _Stall:
    """Tracks progress of the item phase: nudges allowed until the stall limit."""

    def __init__(self, limit_s: float) -> None:
        self.limit_s = limit_s
        self._loop = asyncio.get_running_loop()
        self.since = self._loop.time()

    def progressed(self) -> None:
        self.since = self._loop.time()

    def exceeded(self) -> bool:
        return self._loop.time() - self.since > self.limit_s


class MissionClient:
    """Mission transfers with one vehicle; one transfer at a time per vehicle."""

    def __init__(self, link: VehicleLink, policy: TransferPolicy | None = None) -> None:
        self.link = link
        self.policy = policy or TransferPolicy()
        self._busy = asyncio.Lock()

    # --- upload ------------------------------------------------------------------------

    async def upload(self, mission: Mission, *, verify: bool = True) -> UploadResult:
        """Write `mission`, then read it back and compare item by item (failure mode 6)."""
        self._check_flavour(mission)
        loop = asyncio.get_running_loop()
        started = loop.time()
        async with self._busy:
            await self._until_booted()
            resends = await self._upload_with_retry(mission.items, MISSION_TYPE_MISSION)
            if verify and mission.items:
                self._verify(mission, await self._download())
        seconds = loop.time() - started
        return UploadResult(self.link.sysid, len(mission), seconds, resends, verify)

    async def upload_list(
        self,
        items: tuple[MissionItem, ...],
        mission_type: int,
        same: Callable[[MissionItem, MissionItem], bool],
    ) -> UploadResult:
        """Write a FENCE or RALLY list, then read it back and compare each item with
        `same(sent, read)` (what the autopilot keeps of it); MissionMismatchError names
        the first that differs. An interrupted upload leaves the vehicle's previous list
        (ArduPilot stages it), as for a mission."""
        if mission_type == MISSION_TYPE_MISSION:
            raise ValueError("a mission goes through upload(), which knows ArduPilot's home")
        loop = asyncio.get_running_loop()
        started = loop.time()
        async with self._busy:
            await self._until_booted()
            resends = await self._upload_with_retry(items, mission_type)
            read_back = await self._download(mission_type)
        name = TYPE_NAMES.get(mission_type, f"type {mission_type}")
        if len(read_back) != len(items):
            raise MissionMismatchError(
                self.link.sysid,
                min(len(read_back), len(items)),
                f"{name}: vehicle holds {len(read_back)} items, {len(items)} were sent",
            )
        for seq, (sent, read) in enumerate(zip(items, read_back, strict=True)):
            if not same(sent, read):
                raise MissionMismatchError(
                    self.link.sysid, seq, f"{name}: sent {sent}, vehicle holds {read}"
                )
        seconds = loop.time() - started
        return UploadResult(self.link.sysid, len(items), seconds, resends, True)

    async def _until_booted(self) -> None:
        """A booting ArduPilot refuses every MISSION_COUNT with NO_SPACE (its mission
        storage is not ready): wait for its HEARTBEAT to leave MAV_STATE_BOOT, bounded."""
        link, bound = self.link, self.link.settings.boot_timeout_s
        if not link.state.booting:
            return
        try:
            await link.wait_for("HEARTBEAT", lambda hb: hb.system_status != MAV_STATE_BOOT, bound)
        except WaitTimeoutError:
            raise MissionTimeoutError(
                f"vehicle {link.sysid} was still booting after {bound:.0f} s: no upload yet"
            ) from None

    async def _upload_with_retry(self, items: tuple[MissionItem, ...], mission_type: int) -> int:
        attempt, boot_waits = 1, 0
        while True:
            try:
                return await self._upload_once(items, mission_type)
            except NoSpaceError:
                boot_waits += 1
                if not self.link.state.booting or boot_waits > BOOT_WAITS:
                    raise
                await self._until_booted()  # "not yet", not "too many items"
            except (MissionRejectedError, MissionTimeoutError) as exc:
                definitive = isinstance(exc, MissionRejectedError) and exc.definitive
                if definitive or attempt >= self.policy.whole_transfer_attempts:
                    raise
                self.link.ensure_up()  # a vehicle gone is not waited for again
                attempt += 1

    async def _upload_once(self, items: tuple[MissionItem, ...], mission_type: int) -> int:
        link, n = self.link, len(items)
        count = link.codec.mission_count_encode(link.sysid, link.compid, n, mission_type)
        with link.subscribe((*REQUESTS, "MISSION_ACK")) as sub:
            link.ensure_up()
            first = await self._opening(
                sub,
                count,
                _operation("upload", mission_type),
                _opens_upload(n, mission_type),
                idempotent=False,
                mission_type=mission_type,
            )
            return await self._serve_items(sub, items, first, mission_type)

    async def _serve_items(
        self, sub: Subscription, items: tuple[MissionItem, ...], msg: Any, mission_type: int
    ) -> int:
        """Answer requests until the final ACK; returns how many nudges it took."""
        highest, last_sent, nudges = -1, None, 0
        stall = _Stall(self.policy.stall_limit_s)
        while True:
            if msg is None:
                if stall.exceeded():
                    raise self._upload_stalled(highest, len(items))
                if last_sent is not None:
                    self._send_item(items, last_sent, mission_type)
                    nudges += 1
            elif msg.get_type() == "MISSION_ACK":
                if self._upload_finished(msg, items, highest, last_sent, mission_type):
                    return nudges
            elif 0 <= msg.seq < len(items) and _is_type(msg, mission_type):
                self._send_item(items, msg.seq, mission_type)  # duplicates are answered too
                last_sent = msg.seq
                if msg.seq > highest:
                    highest = msg.seq
                    stall.progressed()
            msg = await _next_or_none(sub, self.policy.item_timeout_s)

    def _upload_finished(
        self,
        ack: Any,
        items: tuple[MissionItem, ...],
        highest: int,
        last_sent: int | None,
        mission_type: int,
    ) -> bool:
        if not _is_type(ack, mission_type):
            return False
        if ack.type == MissionResult.ACCEPTED:
            # An ACCEPTED before the last item was asked for is a stale one.
            return len(items) == 0 or highest == len(items) - 1
        if ack.type == MissionResult.INVALID_SEQUENCE:
            return False  # failure mode 3: the vehicle re-requests what it wants
        raise mission_error(
            self.link.sysid, ack.type, _operation("upload", mission_type), last_sent
        )

    def _send_item(self, items: tuple[MissionItem, ...], seq: int, mission_type: int) -> None:
        link, item = self.link, items[seq]
        link.send(
            link.codec.mission_item_int_encode(
                link.sysid,
                link.compid,
                seq,
                int(item.frame),
                int(item.command),
                0,
                int(item.autocontinue),
                *item.params,
                item.x,
                item.y,
                item.z,
                mission_type,
            )
        )

    def _upload_stalled(self, highest: int, n: int) -> MissionTimeoutError:
        sysid, limit = self.link.sysid, self.policy.stall_limit_s
        if highest == n - 1:
            return MissionTimeoutError(
                f"vehicle {sysid}: no final MISSION_ACK after the last item "
                f"(re-sent for {limit:.1f} s)"
            )
        return MissionTimeoutError(
            f"vehicle {sysid} stopped requesting items after seq {highest} of {n} "
            f"(nothing for {limit:.1f} s)"
        )

    def _verify(self, mission: Mission, read_back: tuple[MissionItem, ...]) -> None:
        seq = first_mismatch(mission, read_back)
        if seq is None:
            return
        if len(read_back) != len(mission):
            detail = f"vehicle holds {len(read_back)} items, {len(mission)} were sent"
        else:
            detail = f"sent {mission.items[seq]}, vehicle holds {read_back[seq]}"
        raise MissionMismatchError(self.link.sysid, seq, detail)

    def _check_flavour(self, mission: Mission) -> None:
        if int(mission.autopilot) != int(self.link.autopilot):
            raise MissionTransferError(
                f"vehicle {self.link.sysid} is {self.link.autopilot.name} but the mission was "
                f"built for {mission.autopilot.name} (seq 0 would be misread)"
            )

    # --- download ----------------------------------------------------------------------

    async def download(self, mission_type: int = MISSION_TYPE_MISSION) -> tuple[MissionItem, ...]:
        """The mission (or fence, or rally points) the vehicle holds (ArduPilot's
        mission: seq 0 is its current home)."""
        async with self._busy:
            return await self._download(mission_type)

    async def _download(self, mission_type: int = MISSION_TYPE_MISSION) -> tuple[MissionItem, ...]:
        link = self.link
        request = link.codec.mission_request_list_encode(link.sysid, link.compid, mission_type)
        types = ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK")
        with link.subscribe(types) as sub:
            link.ensure_up()
            count_msg = await self._opening(
                sub,
                request,
                _operation("download", mission_type),
                lambda m: m.get_type() == "MISSION_COUNT" and _is_type(m, mission_type),
                mission_type=mission_type,
            )
            items = [
                await self._fetch_item(sub, seq, mission_type) for seq in range(count_msg.count)
            ]
        link.send(
            link.codec.mission_ack_encode(
                link.sysid, link.compid, MissionResult.ACCEPTED, mission_type
            )
        )
        return tuple(items)

    async def _fetch_item(self, sub: Subscription, seq: int, mission_type: int) -> MissionItem:
        link = self.link
        request = link.codec.mission_request_int_encode(link.sysid, link.compid, seq, mission_type)
        stall = _Stall(self.policy.stall_limit_s)
        while not stall.exceeded():
            link.send(request)
            msg = await _next_or_none(sub, self.policy.item_timeout_s)
            while msg is not None:
                if _is_refusal(msg, mission_type, definitive_only=True):
                    raise mission_error(
                        link.sysid, msg.type, _operation("download", mission_type), seq
                    )
                if (
                    msg.get_type() in ("MISSION_ITEM_INT", "MISSION_ITEM")
                    and msg.seq == seq
                    and _is_type(msg, mission_type)
                ):
                    return _item_from(msg)
                msg = await _next_or_none(sub, self.policy.item_timeout_s)
        raise MissionTimeoutError(
            f"vehicle {link.sysid} did not send item {seq} within {self.policy.stall_limit_s:.1f} s"
        )

    # --- clear and set current -----------------------------------------------------------

    async def clear(self) -> None:
        """Remove the vehicle's mission (MISSION_CLEAR_ALL, answered by MISSION_ACK)."""
        link = self.link
        msg = link.codec.mission_clear_all_encode(link.sysid, link.compid, MISSION_TYPE_MISSION)
        async with self._busy:
            with link.subscribe(["MISSION_ACK"]) as sub:
                link.ensure_up()
                ack = await self._opening(
                    sub, msg, "clear", lambda m: _is_type(m, MISSION_TYPE_MISSION)
                )
        if ack.type != MissionResult.ACCEPTED:
            raise mission_error(link.sysid, ack.type, "clear")

    async def set_current(self, seq: int) -> None:
        """Make `seq` the item the vehicle flies next (ArduCopter flies it afresh from where
        it is, even if it is the current one): DO_SET_MISSION_CURRENT, acknowledged.

        The MISSION_SET_CURRENT message has no answer of its own: the MISSION_CURRENT taken
        for one is streamed anyway, so when the vehicle already flew `seq` a lost message
        looked done (fuzzed flight 3569: an approach's item was not flown afresh, its
        resume ran the paused S-curve back up to 5.5 m/s, and the next pause stopped it
        0.5 m from another vehicle). An autopilot without the command gets the message."""
        link = self.link
        async with self._busy:
            try:
                await send_command(
                    link, mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT, seq, policy=URGENT
                )
                return
            except CommandUnsupportedError:
                pass
            msg = link.codec.mission_set_current_encode(link.sysid, link.compid, seq)
            with link.subscribe(["MISSION_CURRENT"]) as sub:
                link.ensure_up()
                await self._opening(sub, msg, f"set-current to {seq}", lambda m: m.seq == seq)

    # --- shared --------------------------------------------------------------------------

    async def _opening(
        self,
        sub: Subscription,
        msg: Any,
        operation: str,
        accept: Any,
        *,
        idempotent: bool = True,
        mission_type: int = MISSION_TYPE_MISSION,
    ) -> Any:
        """Send `msg` and return the first answer `accept`s, re-sending it while none comes.

        MISSION_COUNT restarts an upload, so it is re-sent only every `step_timeout_s`,
        at most `retries` times. The other openings (request list, clear, set current)
        change nothing when repeated: they are re-sent every `item_timeout_s` within the
        same overall bound, which keeps a lossy link from failing a verification.
        A refusing MISSION_ACK ends the exchange with its typed error; for an idempotent
        request a transient one (ERROR, CANCELLED) is taken for the vehicle's answer to a
        late packet of an earlier exchange and ignored.
        """
        policy = self.policy
        period = policy.item_timeout_s if idempotent else policy.step_timeout_s
        attempts = round(policy.stall_limit_s / period)
        loop = asyncio.get_running_loop()
        for _ in range(attempts):
            self.link.send(msg)
            deadline = loop.time() + period
            while (answer := await _next_or_none(sub, deadline - loop.time())) is not None:
                if _is_refusal(answer, mission_type, definitive_only=idempotent):
                    raise mission_error(self.link.sysid, answer.type, operation)
                if accept(answer):
                    return answer
        raise MissionTimeoutError(
            f"vehicle {self.link.sysid} did not answer the {operation} within "
            f"{policy.stall_limit_s:.1f} s ({attempts} tries)"
        )


def first_mismatch(sent: Mission, read_back: tuple[MissionItem, ...]) -> int | None:
    """The first seq at which the vehicle holds something else than what it was sent, as
    far as the autopilot keeps it: ArduPilot rebuilds its items (`ardupilot.same_stored`;
    its seq 0 is its current home, not compared), PX4 keeps them as sent (float32)."""
    if len(read_back) != len(sent):
        return min(len(read_back), len(sent))
    if sent.autopilot != Autopilot.ARDUPILOT:
        return sent.first_differing(read_back)
    for seq in range(1, len(sent)):
        if not ardupilot.same_stored(sent.items[seq], read_back[seq]):
            return seq
    return None


async def _next_or_none(sub: Subscription, timeout: float) -> Any:
    try:
        return await sub.get(max(0.0, timeout))
    except WaitTimeoutError:
        return None


def _is_type(msg: Any, mission_type: int) -> bool:
    kind: int = getattr(msg, "mission_type", MISSION_TYPE_MISSION)
    return kind == mission_type


def _operation(what: str, mission_type: int) -> str:
    """ "upload" for a mission, "fence upload" for a fence..."""
    if mission_type == MISSION_TYPE_MISSION:
        return what
    return f"{TYPE_NAMES.get(mission_type, f'type {mission_type}')} {what}"


def _opens_upload(n: int, mission_type: int = MISSION_TYPE_MISSION) -> Any:
    """What answers MISSION_COUNT: a request, or for an empty list the ACK itself."""

    def accept(msg: Any) -> bool:
        if not _is_type(msg, mission_type):
            return False
        return msg.get_type() in REQUESTS or (n == 0 and msg.get_type() == "MISSION_ACK")

    return accept


def _is_refusal(
    msg: Any, mission_type: int = MISSION_TYPE_MISSION, definitive_only: bool = False
) -> bool:
    """A MISSION_ACK that ends the exchange (INVALID_SEQUENCE does not: failure mode 3)."""
    if msg.get_type() != "MISSION_ACK" or not _is_type(msg, mission_type):
        return False
    if msg.type in (MissionResult.ACCEPTED, MissionResult.INVALID_SEQUENCE):
        return False
    return not definitive_only or mission_error(0, msg.type, "").definitive


def _item_from(msg: Any) -> MissionItem:
    if msg.get_type() == "MISSION_ITEM_INT":
        x, y = msg.x, msg.y
    else:  # legacy MISSION_ITEM: float degrees
        x, y = round(msg.x * 1e7), round(msg.y * 1e7)
    return MissionItem(
        command=msg.command,
        frame=msg.frame,
        params=(msg.param1, msg.param2, msg.param3, msg.param4),
        x=x,
        y=y,
        z=msg.z,
        autocontinue=bool(msg.autocontinue),
    )

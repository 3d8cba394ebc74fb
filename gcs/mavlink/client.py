"""Opening links to vehicles: find the autopilot on a connection, then keep its telemetry.

`connect(url)` opens the connection a string names; `attach(connection)` makes a link on
one already open (several vehicles on one port, or an in-memory transport in tests).
Both wait for the autopilot's HEARTBEAT (ignoring ground stations, cameras, gimbals,
companion computers), make the link, and, unless told not to, ask for the telemetry
streams the ground station follows (a real ArduPilot sends nothing else until asked).
`identify(link)` asks which vehicle it is (`gcs.mavlink.identity`).
"""

from __future__ import annotations

import asyncio
import contextlib

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.commands import CommandPolicy, send_command
from gcs.mavlink.connection import MavConnection, Message, Signing
from gcs.mavlink.errors import ConnectTimeoutError, GcsError, WaitTimeoutError
from gcs.mavlink.identity import VehicleIdentity, identity_of
from gcs.mavlink.link import LinkSettings, VehicleLink
from gcs.mavlink.telemetry import TelemetryStreams
from gcs.mavlink.transport import TransportOpener, open_transport

ASK_POLICY = CommandPolicy(timeout_s=1.0, retries=2)
"""An old autopilot may not know REQUEST_MESSAGE; three tries are enough to ask."""
ANSWER_TIMEOUT_S = 1.0
"""How long AUTOPILOT_VERSION may trail the command's ACK."""
NOT_AUTOPILOT_TYPES = frozenset(
    {
        mavlink2.MAV_TYPE_GCS,
        mavlink2.MAV_TYPE_ONBOARD_CONTROLLER,
        mavlink2.MAV_TYPE_GIMBAL,
        mavlink2.MAV_TYPE_ADSB,
        mavlink2.MAV_TYPE_CAMERA,
    }
)


async def connect(
    url: str,
    *,
    sysid: int | None = None,
    settings: LinkSettings | None = None,
    signing: Signing | None = None,
    opener: TransportOpener = open_transport,
) -> VehicleLink:
    """Open `url` and the link to the autopilot `sysid` (the first one heard if None)."""
    connection = await MavConnection.open(url, signing=signing, opener=opener)
    try:
        return await attach(connection, sysid=sysid, settings=settings, owns=True)
    except BaseException:
        await connection.close()
        raise


async def attach(
    connection: MavConnection,
    *,
    sysid: int | None = None,
    settings: LinkSettings | None = None,
    owns: bool = False,
) -> VehicleLink:
    """A link on an already open connection; `owns`: closing the link closes it too."""
    settings = settings or LinkSettings()
    heartbeat = await first_autopilot_heartbeat(connection, sysid, settings.connect_timeout_s)
    link = VehicleLink(connection, heartbeat, settings, owns_connection=owns)
    if settings.request_streams:
        await TelemetryStreams(link, settings.stream_rates_hz).start()
    return link


def is_autopilot_heartbeat(msg: Message, sysid: int | None = None) -> bool:
    return bool(
        msg.get_type() == "HEARTBEAT"
        and msg.autopilot != mavlink2.MAV_AUTOPILOT_INVALID
        and msg.type not in NOT_AUTOPILOT_TYPES
        and (sysid is None or msg.get_srcSystem() == sysid)
    )


async def first_autopilot_heartbeat(
    connection: MavConnection, sysid: int | None, timeout: float
) -> Message:
    found: asyncio.Future[Message] = asyncio.get_running_loop().create_future()

    def look(msg: Message) -> None:
        if not found.done() and is_autopilot_heartbeat(msg, sysid):
            found.set_result(msg)

    stop = connection.listen(look)
    try:
        async with asyncio.timeout(timeout):
            return await found
    except TimeoutError:
        who = f"autopilot {sysid}" if sysid is not None else "an autopilot"
        raise ConnectTimeoutError(
            f"no HEARTBEAT from {who} on {connection.name} within {timeout:.1f} s"
            f"{connection.refusals()}"
        ) from None
    finally:
        stop()


async def identify(link: VehicleLink) -> VehicleIdentity | None:
    """The vehicle's identity, asked for once per link and kept on it; None while the
    vehicle does not answer (asked again next time)."""
    if link.identity is not None:
        return link.identity
    with link.subscribe(["AUTOPILOT_VERSION"]) as sub:
        try:
            await _ask(link)
            msg = await sub.next_matching(None, ANSWER_TIMEOUT_S)
        except (GcsError, WaitTimeoutError):
            return None
    link.identity = identity_of(msg, link.sysid)
    return link.identity


async def _ask(link: VehicleLink) -> None:
    """REQUEST_MESSAGE, or the older REQUEST_AUTOPILOT_CAPABILITIES where it is refused."""
    with contextlib.suppress(GcsError):
        await send_command(
            link,
            mavlink2.MAV_CMD_REQUEST_MESSAGE,
            mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
            policy=ASK_POLICY,
        )
        return
    await send_command(link, mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1, policy=ASK_POLICY)

"""MAVLink 2 message signing for one vehicle, with pymavlink's own implementation.

A vehicle given a secret key signs everything it sends and accepts only packets signed
with that key (pymavlink checks the SHA-256 signature and that each stream's timestamp
moves forward). Like ArduPilot (`GCS_MAVLINK::accept_unsigned_callback`), it lets only
RADIO_STATUS through unsigned; everything else unsigned or wrongly signed is dropped
and counted, so a test can tell "ignored" from "never arrived".
"""

from __future__ import annotations

import hashlib
import time

from pymavlink.dialects.v20 import ardupilotmega as mavlink

SIGNING_EPOCH = 1420070400
"""1 January 2015 UTC: MAVLink signing timestamps count 10 µs units from here."""
UNSIGNED_ALLOWED = frozenset({mavlink.MAVLINK_MSG_ID_RADIO_STATUS})


def key_from_passphrase(passphrase: str) -> bytes:
    """The 32-byte key MAVProxy's `signing setup PASSPHRASE` derives (SHA-256 of the text)."""
    return hashlib.sha256(passphrase.encode()).digest()


def parse_key(text: str) -> bytes:
    """A key given on the command line: 64 hex digits, or any other text as a passphrase."""
    try:
        key = bytes.fromhex(text)
    except ValueError:
        return key_from_passphrase(text)
    return key if len(key) == 32 else key_from_passphrase(text)


def signing_timestamp(wall_time: float | None = None) -> int:
    """Now in MAVLink signing units (wall-clock: timestamps are a protocol matter)."""
    now = time.time() if wall_time is None else wall_time
    return int((now - SIGNING_EPOCH) * 100_000)


def sign_outgoing(mav: mavlink.MAVLink, key: bytes, wall_time: float | None = None) -> None:
    """Make `mav` sign every packet it packs from now on."""
    mav.signing.secret_key = key
    mav.signing.sign_outgoing = True
    mav.signing.link_id = 0
    mav.signing.timestamp = signing_timestamp(wall_time)


def keep_current(mav: mavlink.MAVLink, wall_time: float) -> None:
    """The next packet's timestamp: now, or one tick past the last if that is later.
    pymavlink alone adds one tick (10 µs) a packet, so a stream falls behind the clock
    and after a minute a receiver that starts listening refuses it ("bad new stream")."""
    mav.signing.timestamp = max(mav.signing.timestamp, signing_timestamp(wall_time))


def require_signed(mav: mavlink.MAVLink, key: bytes) -> None:
    """Make `mav` drop packets not signed with `key` (RADIO_STATUS excepted)."""
    mav.signing.secret_key = key
    mav.signing.allow_unsigned_callback = _radio_status_only


def rejected(mav: mavlink.MAVLink) -> int:
    """Packets `mav` dropped for a missing or wrong signature."""
    return int(mav.signing.reject_count)


def _radio_status_only(mav: mavlink.MAVLink, msg_id: int) -> bool:
    return msg_id in UNSIGNED_ALLOWED

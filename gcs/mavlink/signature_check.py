"""Why a packet was refused for its signature, in words an operator can act on.

pymavlink refuses a packet as "Invalid signature" whatever the cause. The causes need
different fixes: no signature (the vehicle does not sign: set its key), another key
(the keys differ), or a timestamp too old (the sender's signing clock is not kept
current, a replay, or a stream that started long before we listened: pymavlink accepts
a new stream only if it is at most a minute behind).
"""

from __future__ import annotations

import hashlib

SIGNED_FLAG = 0x01  # MAVLINK_IFLAG_SIGNED in a MAVLink 2 header's incompat_flags
SIGNATURE_LEN = 13  # link id (1), timestamp (6), signature (6)
TICKS_PER_S = 100_000  # signing timestamps count 10 µs


def why_refused(packet: bytes, key: bytes, our_timestamp: int) -> str:
    """The reason `packet` (a whole MAVLink 2 frame) failed the signature check."""
    if len(packet) < 10 + SIGNATURE_LEN or packet[0] != 0xFD or not packet[2] & SIGNED_FLAG:
        return "unsigned (the vehicle does not sign: give it the key)"
    if hashlib.sha256(key + packet[:-6]).digest()[:6] != packet[-6:]:
        return "signed with another key"
    timestamp = int.from_bytes(packet[-12:-6], "little")
    behind = (our_timestamp - timestamp) / TICKS_PER_S
    return (
        f"its signing timestamp is {behind:.0f} s behind ours or repeats an earlier one "
        "(the sender's signing clock is not kept current, or the packet is replayed)"
    )

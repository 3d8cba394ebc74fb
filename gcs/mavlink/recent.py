"""Per-sender state on a listening port, bounded in count and in time.

Anyone who can send a datagram to a listening port can make per-sender state grow: a
parser, a place in the heartbeat's broadcast list. `Recent` keeps at most `limit`
senders and forgets each `expiry_s` after it was last heard, so a flood of addresses
costs a bounded amount of memory and work, and a sender that stopped costs nothing.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterator
from typing import Generic, TypeVar

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")

SENDER_LIMIT = 64
"""Senders kept per listening port: vehicles, a MAVProxy or two, their companions."""
SENDER_EXPIRY_S = 30.0
"""A sender silent this long is forgotten (a vehicle sends a HEARTBEAT every second)."""


class Recent(Generic[K, V]):
    def __init__(
        self,
        clock: Callable[[], float],
        limit: int = SENDER_LIMIT,
        expiry_s: float = SENDER_EXPIRY_S,
    ) -> None:
        self._clock = clock
        self._limit = limit
        self._expiry_s = expiry_s
        self._items: OrderedDict[K, tuple[V, float]] = OrderedDict()

    def touch(self, key: K, make: Callable[[], V]) -> V:
        """The value kept for `key` (made if new), now the most recently heard."""
        now = self._clock()
        found = self._items.pop(key, None)
        value = make() if found is None else found[0]
        self._items[key] = (value, now)
        self._expire(now)
        return value

    def _expire(self, now: float) -> None:
        while self._items:
            oldest, (_, heard) = next(iter(self._items.items()))
            if len(self._items) <= self._limit and now - heard <= self._expiry_s:
                return
            del self._items[oldest]

    def expire(self) -> None:
        self._expire(self._clock())

    def __iter__(self) -> Iterator[K]:
        return iter(list(self._items))

    def __len__(self) -> int:
        return len(self._items)

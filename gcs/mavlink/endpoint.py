"""Connection strings, as pymavlink's mavutil names them, parsed into one canonical form.

`udpout:HOST:PORT` sends to a vehicle listening there, `udpin:HOST:PORT` (mavutil's
`udp:` too) listens for vehicles that send to us, `tcp:HOST:PORT` connects to a
vehicle's TCP server. HOST is an IPv4 literal, a bracketed IPv6 literal (`[::1]`) or a
host name; PORT is 1-65535 in ASCII digits. Two spellings of one endpoint
(`udp:` and `udpin:`, `014560` and `14560`, `LOCALHOST` and `localhost`) have one
canonical form, which is what the service stores and compares; what cannot work
(port 0, port 65536, non-ASCII digits, an unbracketed IPv6 literal) is refused with a
message that says why.
"""

from __future__ import annotations

import asyncio
import ipaddress
import re
import socket
from dataclasses import dataclass
from typing import Literal

from gcs.mavlink.errors import LinkError

Kind = Literal["udpout", "udpin", "tcp"]
ALIASES = {"udp": "udpin", "udpin": "udpin", "udpout": "udpout", "tcp": "tcp"}
RESOLVE_TIMEOUT_S = 3.0
_PORT = re.compile(r"[0-9]{1,10}")  # leading zeros allowed, as mavutil int()s it
_HOST_LABEL = re.compile(r"(?!-)[a-z0-9-]{1,63}(?<!-)")
_USAGE = "expected udpout:HOST:PORT, udpin:HOST:PORT or tcp:HOST:PORT"


class EndpointError(LinkError, ValueError):
    """A connection string that names no endpoint we can open."""


@dataclass(frozen=True)
class Endpoint:
    kind: Kind
    host: str  # an IP literal (IPv6 without brackets) or a lower-case host name
    port: int

    @classmethod
    def parse(cls, url: str) -> Endpoint:
        """The endpoint a connection string names, in canonical form."""
        scheme, sep, rest = url.strip().partition(":")
        kind = ALIASES.get(scheme.lower())
        if not sep or kind is None:
            raise EndpointError(f"bad connection string {url!r}: {_USAGE}")
        host_text, sep, port_text = rest.rpartition(":")
        if not sep or not host_text:
            raise EndpointError(f"bad connection string {url!r}: {_USAGE}")
        return cls(kind, _host(host_text, url), _port(port_text, url))  # type: ignore[arg-type]

    def __str__(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{self.kind}:{host}:{self.port}"

    @property
    def address(self) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
        """The host as an IP address, None for a host name."""
        try:
            return ipaddress.ip_address(self.host)
        except ValueError:
            return None

    @property
    def is_loopback(self) -> bool:
        address = self.address
        return self.host == "localhost" if address is None else address.is_loopback

    @property
    def is_wildcard(self) -> bool:
        """`udpin:0.0.0.0:…` or `[::]`: listening on every interface."""
        address = self.address
        return address is not None and address.is_unspecified

    async def resolved(self, timeout: float = RESOLVE_TIMEOUT_S) -> Endpoint:
        """The same endpoint with its host name resolved to an address (off the event loop:
        asyncio's resolver runs in a thread), so that two names of one host compare equal."""
        if self.address is not None:
            return self
        loop = asyncio.get_running_loop()
        try:
            async with asyncio.timeout(timeout):
                infos = await loop.getaddrinfo(self.host, self.port, type=socket.SOCK_DGRAM)
        except (OSError, TimeoutError) as exc:
            raise EndpointError(f"cannot resolve host {self.host!r} of {self}: {exc}") from exc
        ipv4 = [info for info in infos if info[0] == socket.AF_INET]
        address = str((ipv4 or infos)[0][4][0])
        return Endpoint(self.kind, address, self.port)


def _host(text: str, url: str) -> str:
    if text.startswith("[") and text.endswith("]"):
        try:
            return str(ipaddress.IPv6Address(text[1:-1]))
        except ValueError:
            raise EndpointError(f"{url!r}: {text} is not an IPv6 address") from None
    if ":" in text:
        raise EndpointError(f"{url!r}: write an IPv6 address in brackets, e.g. udpin:[::1]:14550")
    try:
        return str(ipaddress.IPv4Address(text))
    except ValueError:
        pass
    name = text.lower().rstrip(".")
    if (
        not name.isascii()
        or len(name) > 253
        or not all(map(_HOST_LABEL.fullmatch, name.split(".")))
    ):
        raise EndpointError(f"{url!r}: {text!r} is neither an IP address nor a host name")
    if all(label.isdigit() for label in name.split(".")):
        raise EndpointError(f"{url!r}: {text!r} is not a valid IPv4 address")
    return name


def _port(text: str, url: str) -> int:
    if not _PORT.fullmatch(text):
        raise EndpointError(f"{url!r}: the port must be a number from 1 to 65535, got {text!r}")
    port = int(text)
    if not 1 <= port <= 65535:
        raise EndpointError(f"{url!r}: the port must be from 1 to 65535, got {port}")
    return port

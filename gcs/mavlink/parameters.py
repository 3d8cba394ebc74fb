"""The parameter protocol, client side: set one parameter and see the vehicle confirm it.

PARAM_SET is answered by a PARAM_VALUE with the parameter's new value (or its old one,
if the vehicle refused); it is re-sent while no answer comes, within a bound.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs.mavlink.errors import GcsError, WaitTimeoutError
from gcs.mavlink.link import VehicleLink

ANSWER_TIMEOUT_S = 1.0
ATTEMPTS = 8
"""Tries of a PARAM_SET. With 20 % loss each way a try goes unanswered 36 % of the time:
four left one parameter in 60 unset, and an upload sets several on every vehicle (a
six-UAV flight at 20 % loss was refused for "did not confirm FS_OPTIONS = 24 after 4
tries"). Eight leave one in 3,500."""
LOOKUP_ATTEMPTS = 4
"""Tries of a PARAM_REQUEST_READ. A parameter the vehicle does not have (an older
firmware's) is never answered, so a lookup waits out every try: 4 s, within the link's
timeout while nothing else is heard."""


class ParameterError(GcsError):
    """A parameter the vehicle did not take."""


async def set_parameter(link: VehicleLink, name: str, value: float) -> float:
    """Set `name` to `value` (a REAL32 parameter); the value the vehicle now holds."""
    encoded = name.encode()
    message = link.codec.param_set_encode(
        link.sysid, link.compid, encoded, float(value), mavlink2.MAV_PARAM_TYPE_REAL32
    )
    link.ensure_up()
    with link.subscribe(["PARAM_VALUE"]) as sub:
        for _ in range(ATTEMPTS):
            link.send(message)
            try:
                answer = await sub.next_matching(lambda m: _named(m) == name, ANSWER_TIMEOUT_S)
            except WaitTimeoutError:
                continue
            held = float(answer.param_value)
            if not math.isclose(held, float(np.float32(value)), rel_tol=1e-6, abs_tol=1e-6):
                raise ParameterError(f"vehicle {link.sysid} kept {name} = {held} (asked {value})")
            return held
    raise ParameterError(
        f"vehicle {link.sysid} did not confirm {name} = {value} after {ATTEMPTS} tries"
    )


async def find_parameter(link: VehicleLink, names: Sequence[str]) -> tuple[str, float] | None:
    """The first of `names` the vehicle has, with its value (firmware versions rename
    parameters); all asked for at once with PARAM_REQUEST_READ, None if none answers."""
    wanted = set(names)
    link.ensure_up()
    with link.subscribe(["PARAM_VALUE"]) as sub:
        for _ in range(LOOKUP_ATTEMPTS):
            for name in names:
                link.send(
                    link.codec.param_request_read_encode(link.sysid, link.compid, name.encode(), -1)
                )
            try:
                answer = await sub.next_matching(lambda m: _named(m) in wanted, ANSWER_TIMEOUT_S)
            except WaitTimeoutError:
                continue
            return _named(answer), float(answer.param_value)
    return None


async def set_in_units(
    link: VehicleLink, candidates: Sequence[tuple[str, float]], value: float
) -> str:
    """Set whichever of `candidates` (name, units per given unit) the vehicle has to
    `value`; the name it was set under."""
    scale = dict(candidates)
    found = await find_parameter(link, [name for name, _ in candidates])
    if found is None:
        raise ParameterError(
            f"vehicle {link.sysid} has none of {', '.join(scale)}: cannot set it to {value}"
        )
    name = found[0]
    await set_parameter(link, name, value * scale[name])
    return name


def _named(msg: Any) -> str:
    raw = msg.param_id
    text = raw if isinstance(raw, str) else bytes(raw).decode(errors="replace")
    return text.rstrip("\x00")

"""Mission results as typed errors and the retry policy."""

from __future__ import annotations

import pytest

from gcs.mavlink.errors import (
    InvalidParamError,
    MissionCancelledError,
    MissionDeniedError,
    MissionGenericError,
    MissionResult,
    NoSpaceError,
    UnsupportedCommandError,
    UnsupportedFrameError,
    mission_error,
)
from gcs.mavlink.mission_protocol import TransferPolicy


@pytest.mark.parametrize(
    ("result", "cls", "definitive"),
    [
        (MissionResult.ERROR, MissionGenericError, False),
        (MissionResult.UNSUPPORTED_FRAME, UnsupportedFrameError, True),
        (MissionResult.UNSUPPORTED, UnsupportedCommandError, True),
        (MissionResult.NO_SPACE, NoSpaceError, True),
        (MissionResult.DENIED, MissionDeniedError, True),
        (MissionResult.OPERATION_CANCELLED, MissionCancelledError, False),
    ],
)
def test_every_mission_result_has_its_error(result: int, cls: type, definitive: bool) -> None:
    error = mission_error(7, result, "upload", seq=3)
    assert type(error) is cls
    assert error.definitive is definitive
    assert str(error).startswith("vehicle 7 refused the upload at item seq 3: ")
    assert MissionResult(result).name in str(error)


@pytest.mark.parametrize("param", range(1, 8))
def test_invalid_param_names_the_parameter(param: int) -> None:
    error = mission_error(1, MissionResult.INVALID_PARAM1 + param - 1, "upload", seq=2)
    assert isinstance(error, InvalidParamError)
    assert error.param == param
    assert f"param{param}" in str(error)


def test_every_result_but_accepted_maps_to_an_error() -> None:
    for result in MissionResult:
        if result != MissionResult.ACCEPTED:
            assert mission_error(1, result, "upload").result == result


def test_default_policy_is_the_spec_one() -> None:
    policy = TransferPolicy()
    assert (policy.step_timeout_s, policy.item_timeout_s, policy.retries) == (1.5, 0.25, 5)
    assert policy.stall_limit_s == pytest.approx(9.0)

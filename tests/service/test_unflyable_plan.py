"""An upload the flight's timing refuses: the service answers what is wrong, uploads
nothing, and uploads once the plan can be flown."""

from __future__ import annotations

from typing import Any

import pytest

from gcs.mission.flight_plan import FlightPlan
from gcs.mission.flight_timing import FlightStuck
from tests.inprocess.flying import online, upload_once_online
from tests.inprocess.service import InProcessService, until
from tests.service.test_geofence_upload import flight_on

pytestmark = [pytest.mark.virtual_clock]


async def test_a_plan_whose_order_cannot_be_kept_is_refused_with_nothing_uploaded(
    gcs: InProcessService, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A plan the flight's timing finds stuck (its passing order cannot be kept to the end
    with these vehicles' limits) is a 409 that says so, not a 500 (fuzzed flight 13783),
    and the flight can be uploaded once it can be flown."""
    sim, flight_id = await flight_on(gcs, None)
    vehicle = (await gcs.client.get(f"/flights/{flight_id}")).json()["bindings"]["uav1"]
    await until(lambda: online(gcs.client, vehicle), 20, "the vehicle online")

    def stuck(_flight: FlightPlan) -> Any:
        raise FlightStuck("['uav1'] stopped moving at 12 s of the simulated flight")

    with monkeypatch.context() as patch:
        patch.setattr(FlightPlan, "timed", property(stuck))
        refused = await gcs.client.post(f"/flights/{flight_id}/upload")
    assert refused.status_code == 409, refused.text
    assert "cannot be flown in its passing order" in refused.json()["detail"], refused.text
    assert "stopped moving at 12 s" in refused.json()["detail"], refused.text
    assert len(sim.mission(1)) <= 1  # nothing uploaded
    answer = await upload_once_online(gcs.client, flight_id)
    assert answer["flight"]["state"] == "uploaded", answer

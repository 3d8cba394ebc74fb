"""The vehicle-side mission protocol state machine, driven message by message."""

from __future__ import annotations

import pytest

from sitl_mock.codec import Sender, mavlink
from sitl_mock.flavour import ARDUPILOT, PX4, Flavour
from sitl_mock.mission_item import MissionItem
from sitl_mock.mission_store import MissionStore

GCS = Sender(255, 190, ("udp", ("127.0.0.1", 5000)))
OTHER_GCS = Sender(245, 190, ("udp", ("127.0.0.1", 5001)))
HOME = MissionItem(seq=0, frame=0, command=16, x=473977000, y=85456000, z=488.0)


class Outbox:
    def __init__(self) -> None:
        self.sent: list = []
        self.texts: list[str] = []

    def send(self, msg) -> None:
        self.sent.append(msg)

    def say(self, severity: int, text: str) -> None:
        self.texts.append(text)

    def take(self) -> list:
        sent, self.sent = self.sent, []
        return sent


def make_store(flavour: Flavour = ARDUPILOT, capacity: int = 700) -> tuple[MissionStore, Outbox]:
    out = Outbox()
    return MissionStore(flavour, out, lambda: HOME, capacity), out


def item(seq: int, command: int = 16, frame: int = 6, mission_type: int = 0, **kw):
    return mavlink.MAVLink_mission_item_int_message(
        1,
        1,
        seq,
        frame,
        command,
        0,
        1,
        kw.get("p1", 0),
        0,
        0,
        0,
        473977000 + seq * 1000,
        85456000,
        20.0,
        mission_type,
    )


def count(n: int, mission_type: int = 0):
    return mavlink.MAVLink_mission_count_message(1, 1, n, mission_type)


def acks(sent: list) -> list[int]:
    return [m.type for m in sent if m.get_type() == "MISSION_ACK"]


def requested(sent: list) -> list[int]:
    return [m.seq for m in sent if m.get_type().startswith("MISSION_REQUEST")]


def upload(store: MissionStore, out: Outbox, n: int, sender: Sender = GCS, now: float = 0.0):
    store.handle(count(n), sender, now)
    for seq in range(n):
        store.handle(item(seq), sender, now)
    return out.take()


def test_upload_requests_each_item_with_the_legacy_request_and_acks():
    store, out = make_store()
    store.handle(count(3), GCS, 0.0)
    first = out.take()
    assert [m.get_type() for m in first] == ["MISSION_REQUEST"]
    assert (first[0].target_system, first[0].target_component) == (255, 190)
    store.handle(item(0), GCS, 0.0)
    store.handle(item(1), GCS, 0.0)
    store.handle(item(2), GCS, 0.0)
    sent = out.take()
    assert requested(sent) == [1, 2]
    assert acks(sent) == [mavlink.MAV_MISSION_ACCEPTED]
    assert out.texts == ["Flight plan received"]
    assert store.total == 2
    assert store.items()[0] == HOME


def test_px4_requests_with_request_int_and_has_no_home_item():
    store, out = make_store(PX4)
    sent = upload(store, out, 3)
    assert {m.get_type() for m in sent if m.get_type().startswith("MISSION_REQ")} == {
        "MISSION_REQUEST_INT"
    }
    assert store.total == 3
    assert [i.seq for i in store.items()] == [0, 1, 2]


def test_too_many_items_is_no_space_and_keeps_the_mission():
    store, out = make_store(capacity=5)
    upload(store, out, 3)
    store.handle(count(6), GCS, 1.0)
    assert acks(out.take()) == [mavlink.MAV_MISSION_NO_SPACE]
    assert store.total == 2 and not store.uploading


@pytest.mark.parametrize(
    ("kwargs", "result"),
    [
        ({"frame": mavlink.MAV_FRAME_LOCAL_NED}, mavlink.MAV_MISSION_UNSUPPORTED_FRAME),
        ({"command": mavlink.MAV_CMD_DO_SET_SERVO}, mavlink.MAV_MISSION_UNSUPPORTED),
    ],
)
def test_bad_item_ends_the_upload_and_keeps_the_previous_mission(kwargs, result):
    store, out = make_store()
    upload(store, out, 3)
    before = store.items()
    store.handle(count(4), GCS, 1.0)
    store.handle(item(0), GCS, 1.0)
    store.handle(item(1, **kwargs), GCS, 1.0)
    assert acks(out.take()) == [result]
    assert not store.uploading
    assert store.items() == before


def test_out_of_sequence_item_is_invalid_sequence_and_the_upload_stays_open():
    store, out = make_store()
    store.handle(count(3), GCS, 0.0)
    store.handle(item(0), GCS, 0.0)
    out.take()
    store.handle(item(2), GCS, 0.1)
    assert acks(out.take()) == [mavlink.MAV_MISSION_INVALID_SEQUENCE]
    assert store.uploading
    store.handle(item(1), GCS, 0.2)
    store.handle(item(2), GCS, 0.2)
    assert acks(out.take()) == [mavlink.MAV_MISSION_ACCEPTED]


def test_second_gcs_mid_upload_is_denied_and_the_first_finishes():
    store, out = make_store()
    store.handle(count(2), GCS, 0.0)
    store.handle(count(5), OTHER_GCS, 0.0)
    sent = out.take()
    assert acks(sent) == [mavlink.MAV_MISSION_DENIED]
    assert [m.target_system for m in sent if m.get_type() == "MISSION_ACK"] == [245]
    store.handle(item(0), GCS, 0.0)
    store.handle(item(1), GCS, 0.0)
    assert acks(out.take()) == [mavlink.MAV_MISSION_ACCEPTED]


def test_new_count_from_the_same_gcs_restarts_and_the_old_mission_survives_until_done():
    store, out = make_store()
    upload(store, out, 3)
    before = store.items()
    store.handle(count(4), GCS, 1.0)
    store.handle(item(0), GCS, 1.0)
    store.handle(count(2), GCS, 1.0)  # interrupts: starts over
    assert requested(out.take()) == [0, 1, 0]
    assert store.items() == before
    store.handle(item(0), GCS, 1.0)
    store.handle(item(1), GCS, 1.0)
    assert acks(out.take()) == [mavlink.MAV_MISSION_ACCEPTED]
    assert store.total == 1


def test_silence_re_requests_every_second_then_cancels_after_eight():
    store, out = make_store()
    store.handle(count(3), GCS, 0.0)
    store.handle(item(0), GCS, 0.0)
    out.take()
    for step in range(1, 1000):
        store.tick(step * 0.02)
    sent = out.take()
    assert requested(sent) == [1] * 7  # at 1, 2, ... 7 s
    assert acks(sent) == [mavlink.MAV_MISSION_OPERATION_CANCELLED]
    assert "Mission upload timeout" in out.texts
    assert not store.uploading and store.total == 0


def test_px4_re_requests_every_quarter_second_and_gives_up_after_five():
    store, out = make_store(PX4)
    store.handle(count(3), GCS, 0.0)
    out.take()
    for step in range(1, 400):
        store.tick(step * 0.02)
    sent = out.take()
    assert 18 <= len(requested(sent)) <= 20
    assert acks(sent) == [mavlink.MAV_MISSION_OPERATION_CANCELLED]


def test_duplicate_last_item_after_the_ack_is_re_acked():
    store, out = make_store()
    upload(store, out, 3)
    store.handle(item(2), GCS, 1.0)
    assert acks(out.take()) == [mavlink.MAV_MISSION_ACCEPTED]
    store.handle(item(1), GCS, 1.0)
    assert acks(out.take()) == [mavlink.MAV_MISSION_ERROR]


def test_count_zero_clears():
    store, out = make_store()
    upload(store, out, 3)
    store.handle(count(0), GCS, 1.0)
    assert acks(out.take()) == [mavlink.MAV_MISSION_ACCEPTED]
    assert store.total == 0 and store.items() == [HOME]


def test_download_answers_request_int_with_item_int_and_request_with_item():
    store, out = make_store()
    upload(store, out, 3)
    store.handle(mavlink.MAVLink_mission_request_list_message(1, 1, 0), GCS, 1.0)
    assert [m.count for m in out.take()] == [3]
    store.handle(mavlink.MAVLink_mission_request_int_message(1, 1, 2, 0), GCS, 1.0)
    store.handle(mavlink.MAVLink_mission_request_message(1, 1, 2, 0), GCS, 1.0)
    as_int, as_float = out.take()
    assert as_int.get_type() == "MISSION_ITEM_INT" and as_int.x == 473979000
    assert as_float.get_type() == "MISSION_ITEM" and as_float.x == pytest.approx(47.3979)


def test_fence_and_rally_are_stored_separately_and_clear_all_clears_everything():
    store, out = make_store()
    upload(store, out, 3)
    store.handle(count(1, mission_type=2), GCS, 1.0)
    store.handle(item(0, command=mavlink.MAV_CMD_NAV_RALLY_POINT, mission_type=2), GCS, 1.0)
    assert acks(out.take()) == [mavlink.MAV_MISSION_ACCEPTED]
    assert len(store.items(2)) == 1 and store.total == 2
    store.handle(mavlink.MAVLink_mission_clear_all_message(1, 1, 255), GCS, 2.0)
    assert acks(out.take()) == [mavlink.MAV_MISSION_ACCEPTED]
    assert store.items(2) == [] and store.total == 0


def test_rejecting_vehicle_fails_at_the_chosen_point():
    store, out = make_store()
    store.reject_at = "count"
    store.handle(count(3), GCS, 0.0)
    assert acks(out.take()) == [mavlink.MAV_MISSION_ERROR]
    store.reject_at = "last_item"
    sent = upload(store, out, 3)
    assert requested(sent) == [0, 1, 2] and acks(sent) == [mavlink.MAV_MISSION_ERROR]
    assert store.total == 0


def test_set_current_only_within_the_mission():
    store, out = make_store()
    upload(store, out, 4)
    assert store.set_current(3) and store.current == 3
    assert not store.set_current(4)
    assert not store.set_current(0)  # ArduPilot's home is not flyable

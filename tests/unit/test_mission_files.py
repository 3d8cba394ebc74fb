"""`.plan` and `.waypoints` files: our round trip, pymavlink's reader, and malformed files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink import mavwp

from gcs.mavlink.mission_item import Autopilot, Command, Frame, Mission, MissionItem
from gcs.mission.build import build_missions
from gcs.mission.files import (
    MissionFileError,
    parse_plan,
    parse_waypoints,
    plan_text,
    read_plan,
    read_waypoints,
    waypoints_text,
    write_plan,
    write_waypoints,
)
from planner.cases import CASES, load_case
from planner.pipeline import PlannerSettings, plan

FAST = PlannerSettings(population=10, iterations=20)
FRAMES = [Frame.GLOBAL, Frame.MISSION, Frame.GLOBAL_RELATIVE_ALT, 5, Frame.GLOBAL_RELATIVE_ALT_INT]


def case_missions(autopilot: Autopilot) -> list[Mission]:
    missions: list[Mission] = []
    for case in CASES:
        scenario = load_case(case)
        missions += build_missions(plan(scenario, FAST), scenario, autopilot).values()
    return missions


def assert_same(ours: Mission, theirs: Mission) -> None:
    assert theirs.autopilot == ours.autopilot
    assert ours.first_differing(theirs) is None
    assert all(a.same_as(b) for a, b in zip(ours.items, theirs.items, strict=True))
    if ours.home is not None:
        assert theirs.home == pytest.approx(ours.home, abs=1e-7)


floats = st.floats(allow_infinity=False, width=32)
latitudes, longitudes = (
    st.integers(-900_000_000, 900_000_000),
    st.integers(-1_800_000_000, 1_800_000_000),
)


@st.composite
def items(draw: st.DrawFn) -> MissionItem:
    return MissionItem(
        command=draw(st.integers(0, 65535)),
        frame=draw(st.sampled_from(FRAMES)),
        params=draw(st.tuples(floats, floats, floats, floats)),
        x=draw(latitudes),
        y=draw(longitudes),
        z=draw(floats),
        autocontinue=draw(st.booleans()),
    )


@st.composite
def missions(draw: st.DrawFn) -> Mission:
    """Random items; home on the degE7 grid, which both formats carry exactly."""
    lat, lon, amsl = draw(latitudes), draw(longitudes), draw(st.floats(-500, 9000, width=32))
    home = (lat / 1e7, lon / 1e7, amsl)
    body = tuple(draw(st.lists(items(), max_size=12)))
    if draw(st.booleans()):
        return Mission(body, Autopilot.PX4, home)
    home_item = MissionItem(Command.NAV_WAYPOINT, Frame.GLOBAL, x=lat, y=lon, z=amsl)
    return Mission((home_item, *body), Autopilot.ARDUPILOT, home)


@settings(max_examples=100, deadline=None)
@given(missions())
def test_plan_round_trip(mission: Mission) -> None:
    assert_same(mission, parse_plan(plan_text(mission)))


@settings(max_examples=100, deadline=None)
@given(missions())
def test_waypoints_round_trip(mission: Mission) -> None:
    assert_same(mission, parse_waypoints(waypoints_text(mission), mission.autopilot))


@pytest.mark.parametrize("autopilot", list(Autopilot))
def test_the_paper_cases_round_trip_through_both_files(
    autopilot: Autopilot, tmp_path: Path
) -> None:
    for k, mission in enumerate(case_missions(autopilot)):
        write_plan(mission, tmp_path / f"{k}.plan")
        write_waypoints(mission, tmp_path / f"{k}.waypoints")
        assert_same(mission, read_plan(tmp_path / f"{k}.plan"))
        assert_same(mission, read_waypoints(tmp_path / f"{k}.waypoints", autopilot))


def pymavlink_items(path: Path) -> list:
    loader = mavwp.MAVWPLoader()
    loader.load(str(path))
    return [loader.wp(k) for k in range(loader.count())]


def assert_same_as_pymavlink(ours: MissionItem, theirs, seq: int) -> None:
    """pymavlink's MISSION_ITEM carries lat/lon as float degrees, params and z as floats."""
    scale = 1 if ours.frame == Frame.MISSION else 1e7
    assert theirs.seq == seq
    assert (theirs.command, theirs.frame) == (ours.command, ours.frame)
    assert (round(theirs.x * scale), round(theirs.y * scale)) == (ours.x, ours.y)
    assert bool(theirs.autocontinue) == ours.autocontinue
    again = MissionItem(
        ours.command,
        ours.frame,
        (theirs.param1, theirs.param2, theirs.param3, theirs.param4),
        ours.x,
        ours.y,
        theirs.z,
        ours.autocontinue,
    )
    assert ours.same_as(again)


@pytest.mark.parametrize("autopilot", list(Autopilot))
def test_pymavlink_loads_our_waypoints_into_the_same_items(
    autopilot: Autopilot, tmp_path: Path
) -> None:
    path = tmp_path / "m.waypoints"
    for mission in case_missions(autopilot):
        write_waypoints(mission, path)
        theirs = pymavlink_items(path)
        ours = list(mission.items)
        if autopilot == Autopilot.PX4:  # line 0 is home, not one of PX4's items
            home = parse_waypoints(path.read_text(), Autopilot.ARDUPILOT).items[0]
            ours.insert(0, home)
        assert len(theirs) == len(ours)
        for seq, (a, b) in enumerate(zip(ours, theirs, strict=True)):
            assert_same_as_pymavlink(a, b, seq)
        assert theirs[0].current == 1 and not any(w.current for w in theirs[1:])


@settings(
    max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(mission=missions())
def test_pymavlink_loads_random_missions(mission: Mission, tmp_path: Path) -> None:
    path = tmp_path / "random.waypoints"
    write_waypoints(mission, path)
    theirs = pymavlink_items(path)
    ours = parse_waypoints(path.read_text(), Autopilot.ARDUPILOT).items  # home line included
    for seq, (a, b) in enumerate(zip(ours, theirs, strict=True)):
        assert_same_as_pymavlink(a, b, seq)


def test_we_read_what_pymavlink_writes(tmp_path: Path) -> None:
    """pymavlink saves with %f (6 decimals): same items to 1e-6 degree."""
    mission = case_missions(Autopilot.ARDUPILOT)[0]
    ours, theirs = tmp_path / "ours.waypoints", tmp_path / "theirs.waypoints"
    write_waypoints(mission, ours)
    loader = mavwp.MAVWPLoader()
    loader.load(str(ours))
    loader.save(str(theirs))
    back = read_waypoints(theirs)
    for a, b in zip(mission.items, back.items, strict=True):
        assert (a.command, a.frame, a.autocontinue) == (b.command, b.frame, b.autocontinue)
        assert abs(a.x - b.x) <= 5 and abs(a.y - b.y) <= 5
        assert np.allclose(a.params, b.params, atol=1e-6, equal_nan=True)


GOOD_ITEM = (
    '{"type": "SimpleItem", "command": 16, "frame": 6, "autoContinue": true,'
    ' "params": [0, 0, 0, null, 1.5, 2.5, 20]}'
)


def plan_json(items: str = GOOD_ITEM, firmware: str = "12", home: str = "[1, 2, 3]") -> str:
    return (
        '{"fileType": "Plan", "version": 1, "mission": {"version": 2, "firmwareType": '
        f'{firmware}, "plannedHomePosition": {home}, "items": [{items}]}}}}'
    )


def test_a_minimal_plan_reads() -> None:
    mission = parse_plan(plan_json())
    assert mission.autopilot == Autopilot.PX4 and mission.home == (1, 2, 3)
    (item,) = mission.items
    assert (item.x, item.y, item.z) == (15_000_000, 25_000_000, 20.0)
    assert math.isnan(item.params[3])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{", "line 1: not JSON"),
        ('{"fileType": "Mission", "version": 1}', "fileType is 'Mission', expected 'Plan'"),
        ('{"fileType": "Plan", "version": 1}', "mission is missing"),
        (plan_json(firmware="0"), "firmwareType 0 is neither"),
        (plan_json(home="[1, 2]"), "expected 3 numbers"),
        (plan_json(GOOD_ITEM + ", 7"), "mission.items[1]: must be an object"),
        (plan_json(GOOD_ITEM.replace('"frame": 6, ', "")), "mission.items[0]: frame is missing"),
        (plan_json(GOOD_ITEM.replace("20]", '"20"]')), "mission.items[0]: expected 7 numbers"),
        (plan_json(GOOD_ITEM.replace("null, ", "")), "mission.items[0]: expected 7 numbers"),
        (plan_json(GOOD_ITEM.replace("SimpleItem", "ComplexItem")), "'ComplexItem' is not"),
        (plan_json(GOOD_ITEM.replace("true", "1")), "autoContinue must be bool"),
        (plan_json(GOOD_ITEM.replace('"command": 16', '"command": true')), "command must be"),
    ],
)
def test_malformed_plans_say_what_and_where(text: str, message: str) -> None:
    with pytest.raises(MissionFileError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_plan(text, source="bad.plan")


GOOD_LINE = "0\t1\t0\t16\t0\t0\t0\t0\t-35.3632620\t149.1652370\t584.0\t1"
FRACTIONAL_COMMAND = GOOD_LINE.replace("\t16\t", "\t1.5\t")
SECOND_LINE = GOOD_LINE.replace("0\t1", "1\t0", 1)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "line 1: expected 'QGC WPL 110', found 'an empty file'"),
        ("QGC WPL 100\n", "line 1: expected 'QGC WPL 110', found 'QGC WPL 100'"),
        (f"QGC WPL 110\n{GOOD_LINE}\t7\n", "line 2: expected 12 TAB-separated fields, found 13"),
        (f"QGC WPL 110\n{GOOD_LINE}\n\n{GOOD_LINE}\n", "line 4: INDEX 0 is out of sequence"),
        (f"QGC WPL 110\n{GOOD_LINE.replace('584.0', 'high')}\n", "line 2: ALT 'high' is not"),
        (f"QGC WPL 110\n{FRACTIONAL_COMMAND}\n", "line 2: COMMAND '1.5'"),
        (f"QGC WPL 110\n{GOOD_LINE[:-1]}2\n", "line 2: AUTOCONTINUE must be 0 or 1"),
        (f"QGC WPL 110\n{GOOD_LINE.replace('584.0', 'inf')}\n", "line 2: ALT is infinite"),
    ],
)
def test_malformed_waypoints_say_what_and_where(text: str, message: str) -> None:
    with pytest.raises(MissionFileError, match=message) as error:
        parse_waypoints(text, source="bad.waypoints")
    assert str(error.value).startswith("bad.waypoints: line ")


def test_comments_and_blank_lines_are_skipped_and_px4_line_0_is_home() -> None:
    text = f"QGC WPL 110\n# home\n{GOOD_LINE}\n\n{SECOND_LINE}\n"
    mission = parse_waypoints(text, Autopilot.PX4)
    assert mission.home == pytest.approx((-35.363262, 149.165237, 584.0))
    assert len(mission.items) == 1


def test_writers_refuse_what_the_formats_cannot_hold() -> None:
    homeless = Mission((MissionItem(Command.NAV_LAND),), Autopilot.PX4, None)
    with pytest.raises(ValueError, match="home"):
        plan_text(homeless)
    with pytest.raises(ValueError, match="home"):
        waypoints_text(homeless)
    infinite = Mission((MissionItem(Command.NAV_LAND, z=math.inf),), Autopilot.PX4, (0, 0, 0))
    with pytest.raises(ValueError, match="inf"):
        plan_text(infinite)

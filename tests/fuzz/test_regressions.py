"""Every flight the fuzzer once failed on, flown again: each seed is a defect fixed.

The seed draws the whole flight (tests/fuzz/cases.py), so these replay exactly what
failed, on today's code; `python -m tests.fuzz --seed N --trace` shows one in full."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from tests.fuzz.cases import FuzzCase
from tests.fuzz.runner import fly_seed, run

pytestmark = [pytest.mark.slow, pytest.mark.fuzz]

FOUND = {
    1: "a vehicle stopped near its goal for a leader was never let go again",
    4: "the mock's pause and BRAKE took far longer to stop than ArduCopter's",
    5: "the same, from 5 m/s",
    6: "(the fuzzer's own) a command's effect looked for after a later one had undone it",
    8: "progress was projected onto the wrong part of a path that passes near itself",
    12: "(the fuzzer's own) a hold during take-off looked for in the mission's state only",
    25: "the object stored for a live replan was not the object the operator was told of",
    28: "LAND during lift-off left the mock climbing for ever",
    38: "an abort did not reach the vehicles that came back online after a restart",
    2079: "a hold sent while the passing order resumed a vehicle was undone by that resume "
    "(once the mock resumed at the paused speed, as ArduCopter does: 0.73 m apart)",
    2140: "an abort's LAND, lost on the way, was taken as done on the late ACK of the "
    "operator's re-sent RTL (both DO_SET_MODE): the vehicle stayed in RTL",
    3000: "continue of a vehicle the operator had sent home and then held: a 500 (KeyError)",
    3001: "an approach resumed a paused ArduCopter mission, which ran back up to the speed "
    "it was paused at (the mock now pauses as ArduCopter does): 1.15 m past its limit, "
    "5.82 m apart",
    3017: "found with 3001, clean since approaches keep to their speed: 4.55 m apart at "
    "10 m/s with lossy, late and reordered links",
    3027: "found with 3001, clean since approaches keep to their speed: 5.90 m apart",
    3034: "after a live replan a vehicle was looked for only 3 m along its new path, 5 m on, "
    "and lost; MISSION_SET_CURRENT had given up its pause (0.80 m apart); and the replan "
    "took a held vehicle's timed-flight time for its place on the plan, so the new order "
    "kept it and a replanned one only 3.4 m apart (3.98 m flown)",
    3095: "the operator's continue of a vehicle it had not held took the vehicle for "
    "stopped, and the order then never stopped it creeping through its limit: 3.13 m",
    3294: "a live replan restarted every kept rest at its moment, which brought two kept "
    "UAVs 0.198 cells apart; flown unsafe, the order kept uav2 only 2.69 m from uav5 "
    "(3.54 m flown)",
    4703: "an object report's brake of uav3 was asked for while the order's pause of it "
    "was under way, and the pause's end was taken as the brake; paused, not braked, uav3 "
    "was sent on by its new mission and flew past uav4 (0.63 m)",
    4116: "(the fuzzer's own) uav4 held just as it set off from a waypoint was taken as "
    "standing there, at rest for a moment; its paused S-curve then ran on 2.8 m, as "
    "ArduCopter's does, and that was called moving while held",
    4494: "uav3, kept on its path by an object report, was already inside its encounter "
    "with the replanned uav5 where the rest began; the new order had uav3 wait for uav5, "
    "which flew by it where it stood, 4.10 m away",
    7648: "2 UAVs at 10 m/s, an object report: uav1 was braked for it 12 m short of where "
    "its new path began (foreseen from a pause's reach), and flew from there straight for "
    "its next waypoint (a NAV_TAKEOFF in the air is done at once); the order took it for "
    "standing at its new start and let uav2 by 5.65 m from it",
    8403: "6 UAVs at 10 m/s, 20 % loss in: uav2 stopped 2 m past its limit inside its "
    "encounter with uav1, which stood there too (waiting for uav3), 6.36 m off; it could "
    "not stop short any more, so nobody took the lead, and uav1 went by 5.65 m from uav2. "
    "A vehicle standing still can wait where it stands if the other's way keeps 2R from it",
    11574: "crossing of 6 UAVs at 10 m/s, 20 % loss out on uav6: out of a corner at a "
    "steady 2.66 m/s, uav6 was let go 11.1 m short of its limit, sped up on its next leg, "
    "and its pause ran past the limit to 5.65 m from uav2: a vehicle below its track's "
    "speed now counts as setting off",
    13783: "random 6 UAVs at 10 m/s: the flight's timing found the plan's order stuck "
    "(uav1 and uav3 stopped moving) while it tried landers held short, and the upload "
    "answered 500; a stuck candidate now scores worst, and a hold freed this one",
    11531: "(the mock's) abort with LAND at 10 m/s: the mock's LAND stopped with WP_JERK, "
    "40 % further on than ArduCopter's (PSC_JERK_NE), and uav4 came down 5.82 m from "
    "uav2, which waited for it to pass",
    14852: "gap swap of 6 UAVs at 5 m/s, 20 % loss in and 0.1 s latency on uav5: the "
    "operator's pause, lost, took the late ACK of the continue it had cancelled for its "
    "own; uav5 crept on through the hold to 3.04 m from uav6",
}


@pytest.mark.parametrize("seed", sorted(FOUND))
def test_a_flight_that_once_failed_flies_clean(seed: int) -> None:
    report = fly_seed(seed)
    assert not report.violations, f"{FOUND[seed]}\n{report.summary()}"


FOUND_12 = {
    3428: "with 10 UAVs: the kept UAVs a live replan replanned made a passing order the "
    "flight's timing could not keep (FlightStuck); it was found after the uploads, a 500, "
    "and the vehicles flew their new missions by the old order: 0.16 m",
    3519: "a hold of one vehicle came while the start sent the others AUTO: the start was "
    "cancelled with 8 of 12 vehicles on their missions and nobody keeping the order: 0.21 m",
    3499: "a live replan's rest had two vehicles closer than 2R at once, so the order kept "
    "only 1.66 m between them; a kept vehicle on a path that comes back over itself was "
    "found on the wrong pass after the replan and lost (2.28 m)",
    3401: "vehicles a live replan changed flew on for the 8.5 s of their uploads, then "
    "back to where their new paths began; paused, their new missions sent them on "
    "(0.86 m, also at 3fe2a0e)",
    3522: "a vehicle the order stopped at its start was sent on with the others and paused "
    "at once: its mission, speeding up from rest, went on 2.9 m past a limit 0.8 m ahead "
    "(5.92 m)",
    3530: "the same at 10 m/s, 6 UAVs (5.94 m)",
    3569: "gap swap of 12 UAVs at 10 m/s: an approach's MISSION_SET_CURRENT was lost and "
    "the streamed MISSION_CURRENT taken for its answer; the resume ran the paused S-curve "
    "up to 5.5 m/s, and the next pause stopped it 0.48 m from another vehicle",
    3585: "gap swap of 8 UAVs at 10 m/s: a vehicle whose limit was 1.5 m ahead at the "
    "start was let go (judged at rest) and paused at once; speeding up from its hover it "
    "went on 5.6 m (5.24 m)",
    3606: "random scatter of 12 UAVs at 10 m/s: the same at the start (5.47 m)",
    3621: "crossing of 6 UAVs: the operator sent uav3 home during an abort (land) and "
    "aborted with LAND again; a re-sent RTL held up on uav3's reordering link arrived "
    "after the LAND, and uav3 flew home",
    3790: "crossing of 8 UAVs at 10 m/s: as 3569 (5.18 m)",
    3723: "random scatter of 10 UAVs at 10 m/s: aborted with RTL, then LAND; a copy of "
    "the RTL held up on uav4's link came in right behind the LAND, and uav4 was still in "
    "RTL 1 s after (the HEARTBEAT that showed it came later)",
    3676: "gap swap of 12 UAVs at 5 m/s: during an object report's uploads uav6, kept on "
    "its path, flew on 9 m; the new order (checked before the uploads) had it wait for "
    "uav12 at a place it was 4.5 m past, and uav12 flew up to it (3.75 m)",
    3734: "(the fuzzer's own) a fleet hold sent while the flight was interrupted was taken "
    "as still in force after the operator's resume, which lets every vehicle go",
    3864: "gap swap of 12 UAVs at 5 m/s: as 3723, for uav5",
    3983: "gap swap of 12 UAVs at 5 m/s with a restart: uav5 had stepped aside and come "
    "back, and its next waypoint (where it started) was placed on its path's first pass; "
    "found there and lost, it flew through where uav6 crept (0.11 m)",
    7548: "(the mock's) crossing of 6 UAVs at 10 m/s: uav4's pause ran it 14 m past its "
    "waypoint, which the mock did not count as reached while paused (ArduCopter does: "
    "ModeAuto::run updates the mission throughout); the approach's MISSION_SET_CURRENT "
    "then sent it back to that waypoint, across uav5's way (5.10 m)",
    6698: "crossing of 12 UAVs at 5 m/s with a restart: uav6's pause was lost four times "
    "running (20 % loss in) and it stopped 1.5 m past its limit, inside its encounter with "
    "uav4; nothing re-ordered around a vehicle found inside, and uav4 passed it 5.43 m "
    "away. Now it takes the lead there (`gcs.fleet.lead_taking`)",
    7773: "gap swap of 10 UAVs, 20 % loss in on uav7: a fleet pause during the start came "
    "0.4 s after uav7's ARM was acknowledged, before a HEARTBEAT said it was armed; taken "
    "for on the ground, it was left alone and climbed on in GUIDED",
    9979: "crossing of 10 UAVs at 10 m/s, no operator: uav10, creeping at 0.5 m/s, passed "
    "its mission's speed items (10 m/s) and sped up on its long leg to the landing place; "
    "judged as on its approach, it was stopped too late and came 5.47 m from uav8 (found "
    "once the fuzz runner polled less, at 19dd2a3; also at aa5753c with that runner)",
    11679: "4 UAVs at 5 m/s: the operator held the fleet and reported an object; uav3, "
    "held, got its new mission, whose upload and start gave up its pause, and flew it "
    "during the hold, out of the order; after the continue it came within 0.59 m of uav4",
    11767: "(the mock's) 8 UAVs at 5 m/s: uav7, landed by the operator at 3.4 m/s 3 m "
    "short of its goal, came down 2.9 m past it with the mock's over-long LAND stop, "
    "toward uav8, which the order let come to 2R and its margin of that goal: 5.63 m",
    15490: "gap swap of 12 UAVs at 10 m/s, 20 % loss out on three: answers owed to "
    "re-sent attempts were carried to the next command of their number, whose own answer "
    "was then skipped and re-sent for: brakes 0.2 s late, uav7 and uav10 0.44 m apart "
    "(only a command given up on before any answer now leaves its answers owed)",
    19087: "gap swap of 12 UAVs at 5 m/s, 20 % loss in on uav7: its three "
    "SET_MESSAGE_INTERVALs went unanswered and the fallback REQUEST_DATA_STREAM (which "
    "has no answer) was lost too; asked for nothing more, uav7 never streamed a position "
    "and the start failed after 100 s. The streams are now asked for until they flow",
}
"""Flights of up to 12 UAVs (`--max-uavs 12`), beyond the CI batch's 6."""


@pytest.mark.parametrize("seed", sorted(FOUND_12))
def test_a_larger_flight_that_once_failed_flies_clean(seed: int) -> None:
    report = fly_seed(seed, max_uavs=12)
    assert not report.violations, f"{FOUND_12[seed]}\n{report.summary()}"


FOUND_LINK_DROPS = {
    (1014, 5.0, 6): "crossing of 6 UAVs at 5 m/s, uav4's link silent 5 s while it flew toward "
    "where it was to wait for uav3: its mission flew it on 4.8 m into the encounter, it was "
    "stopped there once heard again, and uav3 passed it 0.65 m away. A vehicle unheard for "
    "1 s now leads every encounter ahead where the other can still stop short",
    (1529, 5.0, 6): "gap swap of 6 UAVs at 10 m/s, uav4's link silent 5 s as it crept from its "
    "start: it flew 8 m unheard, then its GCS failsafe braked it, and heard again it was "
    "looked for only 6 m on (its speeds either side of the silence), taken to stand at its "
    "start for good, while the order let uav1 fly to 4.36 m of it. Its progress now looks "
    "as far on as its cruise can have taken it",
    (19782, 5.0, 12): "random 8 UAVs at 10 m/s, uav2 silent when the start sent it AUTO: "
    "the start asked it again and again for 3.2 s, and the others flew their missions "
    "unfollowed meanwhile; then held for uav2's failed start, uav3 and uav8, speeding up, "
    "ran on into each other's way (5.65 m). The order is now kept from the first answer",
    (19864, 10.0, 12): "gap swap of 8 UAVs at 10 m/s, 20 % loss in on two: uav3, creeping "
    "at 0.5 m/s 6 m short of its limit, passed a DO_CHANGE_SPEED item of its mission and "
    "sped up; paused 1.6 m short once faster than its approach, it ran on 4.6 m, 4.05 m "
    "from uav8. An approach is now given its speed again at each item reached",
    (19888, 2.0, 12): "crossing of 10 UAVs at 10 m/s, uav9 silent during the start: with "
    "the order kept during the start (19782), uav9 was taken to fly on unheard and led "
    "every encounter ahead; its followers were turned round where they stood, two passed "
    "5.30 m apart and the flight stuck. A vehicle whose start is unanswered is not",
    (20014, 2.0, 12): "crossing of 8 UAVs at 5 m/s, 20 % loss both ways on uav3: its "
    "MISSION_CURRENT interval requests and their fallback were lost, so only positions "
    "streamed; an approach restarted the item last seen, 5 s old, and uav3 flew back to "
    "a waypoint it had passed, 1.67 m from uav4 waiting there",
    (20276, 10.0, 12): "gap swap of 8 UAVs at 5 m/s, lossy links: uav7, sent on from a stop "
    "3.1 m short of its limit, had its item made current and fell silent before its speed "
    "came; it flew the item afresh at 5 m/s until its failsafe braked it, 1.3 m past its "
    "limit, and uav1 passed 5.87 m from it. Where the room is short, the speed now goes first",
}
"""Flights with a link drop (`--link-drops`), each with the drop's length it failed with
(the seed draws its moment and vehicle) and the bound on UAVs it was drawn with."""


@pytest.mark.parametrize(("seed", "seconds", "max_uavs"), sorted(FOUND_LINK_DROPS))
def test_a_flight_with_a_link_drop_that_once_failed_flies_clean(
    seed: int, seconds: float, max_uavs: int, tmp_path: Path
) -> None:
    drawn = FuzzCase.draw(seed, max_uavs, link_drops=True)
    actions = tuple(
        dataclasses.replace(a, seconds=seconds) if a.kind == "silence" else a for a in drawn.actions
    )
    report = run(dataclasses.replace(drawn, actions=actions), tmp_path / "data")
    assert not report.violations, f"{FOUND_LINK_DROPS[seed, seconds, max_uavs]}\n{report.summary()}"

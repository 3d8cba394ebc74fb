"""The operator console in a real browser (Debian's Chromium under Playwright) against a
real `mvo-gcs serve` with mock vehicles at case VI's starts: load the case, plan, see the
three paths and their animation, upload, start, watch the vehicles move on the map where
the API says they are, pause (they stop), continue, report an object (a replan), abort.

Every wait is for a condition with a generous bound (a loaded machine is slow, never
wrong); nothing sleeps to let things settle. A browser console error fails the test.
Screenshots go to MVO_GCS_SCREENSHOTS (docs/console/ to refresh the committed ones), else
to the test's temporary directory.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from gcs.fleet.events import FlightEnded, FlightOutcome
from gcs.mission.geodesy import GridFrame
from gcs.service.flights.active import event_json
from gcs.service.settings import Settings
from gcs.service.storage.database import Database
from gcs.service.storage.tables import EventRow
from planner.cases import load_case
from planner.model.trajectory import Trajectory
from sitl_mock import Simulator
from tests.browser.chromium import NEEDS_CHROMIUM, Browser
from tests.e2e.flying import Flight, fleet_at_starts, ground_speed, register, wait_for
from tests.service_process import TOKEN, ServiceProcess

pytestmark = NEEDS_CHROMIUM
pytest.importorskip("playwright.sync_api", reason="playwright is not installed")

SPEEDUP = 5.0  # slow enough that the page can pause and report mid-flight
UAVS = ("uav1", "uav2", "uav3")


@pytest.fixture
def vehicles() -> Iterator[Simulator]:
    sim = fleet_at_starts(load_case("case-6"), speedup=SPEEDUP)
    with sim.running():
        yield sim


# --- where things are on the screen ----------------------------------------------------


SCREEN = """() => {
  const centre = (el) => { const r = el.getBoundingClientRect();
    return [r.left + r.width / 2, r.top + r.height / 2]; };
  const cells = [...document.querySelectorAll('.cell-start, .cell-goal')].map(
    (el) => [el.dataset.cell.split(',').map(Number), centre(el)]);
  const vehicles = Object.fromEntries([...document.querySelectorAll('.vehicle')].map(
    (el) => [el.dataset.uav, centre(el)]));
  return {cells, vehicles};
}"""


class ScreenFrame:
    """Grid cells to screen pixels, fitted to where the page drew the starts and goals."""

    def __init__(self, cells: list[list[Any]]) -> None:
        grid = np.array([[x, y, 1.0] for (x, y), _ in cells])
        pixels = np.array([p for _, p in cells])
        self.matrix, *_ = np.linalg.lstsq(grid, pixels, rcond=None)
        fitted = grid @ self.matrix
        assert np.abs(fitted - pixels).max() < 1.5, "the starts and goals are not on one grid"
        self.cell_px = float(np.linalg.norm(self.matrix[0]))

    def pixel(self, x: float, y: float) -> np.ndarray:
        return np.array([x, y, 1.0]) @ self.matrix

    def cells(self, px: list[float]) -> np.ndarray:
        """Back from pixels to cells (the fit is affine and invertible)."""
        a = self.matrix[:2].T
        return np.linalg.solve(a, np.array(px) - self.matrix[2])


def api_cells(client: httpx.Client, flight_id: str, frame: GridFrame) -> dict[str, np.ndarray]:
    """Where the API says every vehicle is, in cells."""
    live = client.get(f"/flights/{flight_id}/live-state").json()
    out = {}
    for v in live["vehicles"]:
        x, y = frame.to_cells(v["lat"], v["lon"])
        out[v["uav_id"]] = np.array([float(x), float(y)])
    return out


def screen_cells(b: Browser, screen: ScreenFrame) -> dict[str, np.ndarray]:
    drawn = b.js(SCREEN)["vehicles"]
    return {uav: screen.cells(px) for uav, px in drawn.items()}


def worst_gap(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> float:
    assert set(a) == set(b) == set(UAVS), (a, b)
    return max(float(np.linalg.norm(a[k] - b[k])) for k in UAVS)


def state_shown(b: Browser) -> str:
    return str(b.page.inner_text("#flight-state"))


def look_back(b: Browser, flight_id: str) -> str:
    """What the look-back section shows for a stored flight."""
    b.page.click("#lookback-section summary")
    b.page.click("#refresh-flights-btn")
    b.wait_js(
        "(id) => [...document.querySelectorAll('#flight-select option')].some(o => o.value === id)",
        30,
        flight_id,
    )
    b.page.select_option("#flight-select", flight_id)
    b.page.click("#show-flight-btn")
    b.wait_js("() => document.querySelector('#lookback-result').textContent.length > 0", 60)
    text: str = b.page.inner_text("#lookback-result")
    return text


def wait_state(b: Browser, states: tuple[str, ...], timeout_s: float) -> str:
    b.wait_js(
        "(states) => states.includes(document.querySelector('#flight-state').textContent)",
        timeout_s,
        list(states),
    )
    return state_shown(b)


def until(condition: Callable[[], Any], timeout: float, what: str) -> Any:
    return wait_for(condition, timeout, what, every=0.1)


# --- the test ----------------------------------------------------------------------------


def test_an_operator_flies_case_vi_from_the_console(
    service: ServiceProcess, vehicles: Simulator, browser: Browser, shots: Path
) -> None:
    b, page = browser, browser.page
    scenario = load_case("case-6")
    grid = GridFrame.of(scenario)
    with service.client() as client:
        for sysid in vehicles.sysids:  # as `mvo-gcs demo` does before the operator arrives
            register(client, vehicles.connection_string(sysid))

        page.goto(service.url + "/")
        b.wait_js("() => document.body.dataset.ready === 'true'", 30)
        assert page.title() == "mvo-gcs console"

        # Load case VI: three starts and three goals on the grid.
        page.select_option("#case-select", "case-6")
        page.click("#load-case-btn")
        b.wait_js("() => document.querySelectorAll('.cell-start').length === 3", 10)
        screen = ScreenFrame(b.js(SCREEN)["cells"])
        assert screen.cell_px > 20, "cells too small to read at 1280x800"

        # Plan two candidates (the token is asked once, here), watch the job, see three
        # paths: the candidate flown soonest at the Fly section's speed, its seed shown.
        page.fill("#pl-budget", "3")
        page.fill("#pl-candidates", "2")
        page.click("#plan-btn")
        page.wait_for_selector("#token-dialog[open]")
        page.fill("#token-input", TOKEN)
        page.click("#token-ok")
        b.wait_js("() => document.querySelectorAll('.plan-path').length === 3", 90)
        assert "safe" in page.inner_text("#status")
        metrics = page.inner_text("#metrics")
        assert "min separation" in metrics and "first safe after" in metrics
        plan_id = page.inner_text("#plan-id").strip()
        planned = client.get(f"/plans/{plan_id}").json()
        plan = planned["plan"]
        assert plan["feasible"]
        assert f"seed {plan['seed']}" in metrics and plan["seed"] in (1, 2)
        # Each candidate as its flight was timed when chosen (or why it could not be).
        assert "candidates\t2, the soonest flown kept" in metrics, metrics
        for c in planned["candidates"]:
            outcome = (
                f"the same paths as seed {c['same_as']}"
                if c["same_as"] is not None
                else c["refusal"] or f"{c['duration_s']:.1f} s"
            )
            row = f"seed {c['seed']}, {c['clearance_m']:.1f} m\t{outcome}"
            assert row + (" (kept)" if c["kept"] else "") in metrics, (row, metrics)
        assert [c["kept"] for c in planned["candidates"]] == [s == plan["seed"] for s in (1, 2)]
        job = next(j for j in client.get("/jobs").json() if j["plan_id"] == plan_id)
        assert job["settings"]["candidates"] == 2 and job["settings"]["flight_speed_m_s"] == 5
        # How long it flies as the Fly section says (5 m/s, 10 m up, land), before anything
        # is uploaded.
        asked = "max_speed_m_s=5&altitude_m=10&finish=land"
        timing = client.get(f"/plans/{plan_id}/timing?{asked}").json()
        b.wait_js("() => document.querySelector('#timed-flight').textContent !== '…'", 30)
        timed = page.inner_text("#timed-flight")
        assert timed == f"{timing['duration_s']:.1f} s to the last goal at 5.0 m/s", timed
        # Another speed (whatever the service answers: this plan depends on the wall-clock
        # budget, and so does whether 8 m/s can be kept), then one the API refuses.
        text = "document.querySelector('#timed-flight').textContent"
        answer = client.get(f"/plans/{plan_id}/timing?max_speed_m_s=8&altitude_m=10&finish=land")
        expected = (
            f"{answer.json()['duration_s']:.1f} s to the last goal at 8.0 m/s"
            if answer.status_code == 200
            else f"at 8 m/s: {answer.json()['detail']}"
        )
        for speed, shown in (("8", expected), ("25", "at 25 m/s: Input should be less than")):
            page.fill("#fl-speed", speed)
            page.press("#fl-speed", "Tab")
            b.wait_js(f"() => {text}.startsWith({json.dumps(shown)})", 30)
        page.fill("#fl-speed", "5")
        page.press("#fl-speed", "Tab")
        b.wait_js(f"() => {text} === {json.dumps(timed)}", 30)
        refused = [m for m in b.errors if "status of 422" in m]
        assert len(refused) == 1 + (answer.status_code == 422), b.errors  # logged, expected
        b.errors[:] = [m for m in b.errors if m not in refused]

        # Play: the discs move along the paths and the time runs to the plan's end.
        discs_before = b.js(
            "() => [...document.querySelectorAll('.anim-disc')].map(d => d.getAttribute('d'))"
        )
        assert len(discs_before) == 3
        page.click("#play-btn")
        b.wait_js("() => Number(document.querySelector('#time-slider').value) > 1", 30)
        discs_moving = b.js(
            "() => [...document.querySelectorAll('.anim-disc')].map(d => d.getAttribute('d'))"
        )
        assert discs_moving != discs_before
        b.shot(shots, "console-plan.png")
        b.wait_js("() => document.querySelector('#play-btn').textContent === 'Play'", 60)
        end = float(page.input_value("#time-slider"))
        assert end == pytest.approx(max(u["trajectory"][-1][0] for u in plan["uavs"]), abs=0.06)

        # Bind (the page's default: the vehicles in order) and upload, once all are online,
        # at 1 m/s: at the default 5 m/s case VI is over in 6 wall seconds here, before a
        # busy machine's page has paused, continued and reported a bird.
        b.wait_js(
            "() => document.querySelectorAll('#vehicle-table tr[data-online=true]').length === 3",
            60,
        )
        page.fill("#fl-speed", "1")
        page.click("#upload-btn")
        wait_state(b, ("uploaded", "upload_failed"), 120)
        assert state_shown(b) == "uploaded", page.inner_text("#upload-results")
        assert page.locator("#upload-results li.ok").count() == 3
        flight_id = page.inner_text("#flight-id").strip()

        # Start: vehicles appear, then move on the map.
        page.click("#start-btn")
        b.wait_js("() => document.querySelectorAll('.vehicle').length === 3", 60)
        at_start = screen_cells(b, screen)
        for uav, where in at_start.items():
            start = next(u.start for u in scenario.uavs if u.id == uav)
            assert np.linalg.norm(where - np.array(start)) < 0.3, (uav, where, start)
        wait_state(b, ("flying",), 120)
        until(lambda: worst_gap(screen_cells(b, screen), at_start) > 0.5, 60, "vehicles moving")
        # While flying the screen trails the API by a frame or two, no more.
        gap = worst_gap(screen_cells(b, screen), api_cells(client, flight_id, grid))
        assert gap < 1.0, gap

        # Pause: every vehicle stops, and where the page draws it is where the API says.
        page.click("#pause-btn")
        wait_state(b, ("paused",), 60)
        until(lambda: max(ground_speed(vehicles, k) for k in vehicles.sysids) < 0.05, 60, "stop")
        until(
            lambda: worst_gap(screen_cells(b, screen), api_cells(client, flight_id, grid)) < 0.1,
            30,
            "the drawn positions to match the API's",
        )
        stopped = screen_cells(b, screen)
        stopped_at = vehicles.sim_time
        until(lambda: vehicles.sim_time > stopped_at + 10, 30, "10 simulated seconds")
        assert worst_gap(screen_cells(b, screen), stopped) < 0.1
        assert state_shown(b) == "paused"
        b.shot(shots, "console-paused.png")

        # Continue: they move again.
        page.click("#continue-btn")
        wait_state(b, ("flying",), 60)
        until(lambda: worst_gap(screen_cells(b, screen), stopped) > 0.3, 60, "moving again")

        # Report a bird a few seconds (of the plan) ahead of the UAV with the most of its
        # path left, where it is on its own plan (at cruise speed each keeps the plan's
        # passing order, not its clock): the page shows the replan.
        live = client.get(f"/flights/{flight_id}/live-state").json()
        pace = live["pace_factor"]
        trajectories = {u["id"]: Trajectory(np.array(u["trajectory"])) for u in plan["uavs"]}
        here = {v["uav_id"]: v["progress"]["plan_time_s"] / pace for v in live["vehicles"]}
        left = {uav: trajectories[uav].end_time - t for uav, t in here.items()}
        uav = max(left, key=left.__getitem__)
        assert left[uav] > 4.0, f"every UAV is almost at its goal: {left}"
        ahead = trajectories[uav].at([here[uav] + 2.5])[0]
        cell = [round(float(ahead[0])), round(float(ahead[1]))]
        page.click("#report-btn")
        x, y = screen.pixel(*cell)
        page.mouse.click(float(x), float(y))
        page.wait_for_selector("#replan-result [data-field=changed]", timeout=60_000)
        touched = page.inner_text("#replan-result [data-field=touched]")
        changed = page.inner_text("#replan-result [data-field=changed]")
        assert uav in touched, (cell, touched)
        assert uav in changed, (cell, changed)
        assert page.locator(".plan-path.replanned").count() >= 1
        assert page.locator(f".object.reported[data-cell='{cell[0]},{cell[1]}']").count() == 1
        b.wait_js(
            "() => [...document.querySelectorAll('#events li')]"
            ".some(li => li.dataset.kind === 'ObjectReported')",
            30,
        )
        b.shot(shots, "console-flight.png")

        # Abort: every vehicle lands where it is.
        page.click("#abort-land-btn")
        wait_state(b, ("aborting", "aborted"), 30)
        assert wait_state(b, ("aborted",), 180) == "aborted"
        assert client.get(f"/flights/{flight_id}").json()["state"] == "aborted"

        # Look back at it from the stored events.
        assert flight_id in look_back(b, flight_id)
        b.shot(shots, "console-aborted.png")

        timings = b.js("() => window.consoleTimings")
        report = {
            k: round(v / 1000, 3)
            for k, v in timings.items()
            if k != "startClicked" and isinstance(v, float | int)
        }
        (shots / "timings.json").write_text(json.dumps(report, indent=2) + "\n")
        print(f"console timings after start (s): {report}")
        assert timings["firstLiveAfterStart"] > 0

    assert not b.errors, b.errors
    assert not b.foreign, f"the page loaded from outside the service: {b.foreign}"
    assert not service.problems(), service.problems()


def test_api_docs_and_console_load_nothing_from_outside(
    service: ServiceProcess, browser: Browser
) -> None:
    page = browser.page
    page.goto(service.url + "/docs")
    page.wait_for_selector(".swagger-ui .info .title", timeout=60_000)
    assert "mvo-gcs" in page.inner_text(".swagger-ui .info .title")

    page.goto(service.url + "/")
    browser.wait_js("() => document.body.dataset.ready === 'true'", 30)
    # The fleet's commands are reachable from the keyboard, first in the page's order.
    focused = []
    for _ in range(8):
        page.keyboard.press("Tab")
        focused.append(browser.js("() => document.activeElement.id"))
    for button in ("pause-btn", "continue-btn", "abort-rtl-btn", "abort-land-btn"):
        assert button in focused, focused
    assert not browser.errors, browser.errors
    assert not browser.foreign, browser.foreign


def test_validation_errors_appear_next_to_the_fields_they_name(
    service: ServiceProcess, browser: Browser
) -> None:
    page = browser.page
    page.goto(service.url + "/")
    browser.wait_js("() => document.body.dataset.ready === 'true'", 30)
    page.select_option("#case-select", "case-6")
    page.click("#load-case-btn")
    browser.wait_js("() => document.querySelectorAll('.cell-start').length === 3", 10)

    speed = "#uav-table [data-loc='uavs.0.speed']"
    page.fill(speed, "-1")
    page.press(speed, "Tab")
    page.click("#save-scenario-btn")
    page.wait_for_selector("#token-dialog[open]")
    page.fill("#token-input", TOKEN)
    page.click("#token-ok")
    note = page.locator(f"{speed} + .field-error")
    note.wait_for()
    assert "greater than 0" in note.inner_text()
    assert page.get_attribute(speed, "aria-invalid") == "true"

    # The planner's own checks name their field in the message: uav2's start is now off
    # the grid. The token is not asked again.
    page.fill(speed, "1")
    page.press(speed, "Tab")
    page.fill("#sc-width", "5")
    page.press("#sc-width", "Tab")
    page.click("#save-scenario-btn")
    start = page.locator("#uav-table [data-loc='uavs.1.start'] .field-error")
    start.wait_for()
    assert "outside the 5x9 grid" in start.inner_text()
    assert page.locator(f"{speed} + .field-error").count() == 0
    assert "non_uav_objects[1]" in page.inner_text("#scenario-errors")
    assert not page.is_visible("#token-dialog")
    # Chromium logs each refused request; the two 422 answers are the point here.
    unexpected = [m for m in browser.errors if "status of 422" not in m]
    assert not unexpected, unexpected


def test_look_back_reads_every_stored_event_of_a_long_flight(
    service: ServiceProcess, vehicles: Simulator, browser: Browser
) -> None:
    """A flight with more events than one page holds (10 000): the look-back still finds
    its FlightEnded, stored last."""
    page = browser.page
    with service.client() as client:
        flight = Flight.make(client, vehicles, "case-6")
    stored = 10_500
    database = Database(Settings(data_dir=service.data_dir).resolved_database_url)
    ended = FlightEnded(True, 6.54, ("uav1", "uav3"), FlightOutcome.LANDED)
    with database.session() as s:
        s.add_all(
            EventRow(
                flight_id=flight.id,
                kind="Positions",
                data={"type": "event", "kind": "Positions", "clock_s": t, "vehicles": {}},
            )
            for t in range(stored - 1)
        )
        s.add(EventRow(flight_id=flight.id, kind="FlightEnded", data=event_json(ended)))
    database.engine.dispose()

    page.goto(service.url + "/")
    browser.wait_js("() => document.body.dataset.ready === 'true'", 30)
    shown = look_back(browser, flight.id)
    assert "measured separation 6.54 m (uav1 \u2013 uav3), outcome landed" in shown, shown
    assert f"{stored} events" in shown, shown
    assert page.locator("#events li").count() == 200
    assert not browser.errors, browser.errors

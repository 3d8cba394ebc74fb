"""The fleet's events as plain text for a terminal: a progress table and one line per event.

On a terminal the table is redrawn in place (ANSI cursor-up, no curses); into a pipe
or a file it is printed every few seconds instead, so logs stay readable.
"""

from __future__ import annotations

import sys
from typing import TextIO

from gcs.fleet.events import (
    Aborted,
    FleetEvent,
    FlightEnded,
    LeadTaken,
    MissionsStarted,
    Progress,
    StartCancelled,
    Uploaded,
    VehicleFailed,
    VehicleFinished,
    VehicleReady,
    Waiting,
    WaitOver,
)
from gcs.fleet.route_tracker import VehicleProgress

HEADER = f"{'uav':<10} {'mode':<8} {'alt m':>6} {'item':>7} {'next m':>7} {'eta s':>6} {'lag s':>6}"
PIPE_EVERY_S = 5.0


def progress_line(p: VehicleProgress) -> str:
    alt = f"{p.alt_m:6.1f}" if p.alt_m is not None else "     -"
    nxt = f"{p.distance_to_next_m:7.1f}" if p.distance_to_next_m is not None else "      -"
    eta = f"{p.eta_s:6.1f}" if p.eta_s is not None else "     -"
    state = "done" if p.finished else ("paused" if p.paused else "")
    link = "" if p.link_up else " LINK DOWN"
    return (
        f"{p.uav_id:<10} {p.mode:<8} {alt} {p.reached:>3}/{p.items:<3} {nxt} {eta} "
        f"{p.lag_s:6.1f} {state}{link}"
    )


def event_line(event: FleetEvent) -> str | None:
    """One line for the events worth a line; None for the others."""
    match event:
        case Uploaded(uav_id=uav, ok=ok, detail=detail):
            return f"{uav}: mission {'uploaded and verified' if ok else 'FAILED: ' + detail}"
        case VehicleReady(uav_id=uav, altitude_m=alt):
            return f"{uav}: holding at {alt:.0f} m"
        case VehicleFailed(uav_id=uav, phase=phase, message=msg):
            return f"{uav}: {phase} failed: {msg}"
        case StartCancelled(failed=failed, fallback=fallback):
            return f"start cancelled ({', '.join(failed)} failed); the others {fallback}"
        case MissionsStarted(uav_ids=uavs, spread_ms=spread, timed_duration_s=timed):
            return (
                f"{len(uavs)} missions started within {spread:.1f} ms; the last arrives "
                f"in {timed:.0f} s if nothing goes wrong"
            )
        case Waiting(uav_id=uav, waits_for=leader, how=how, gap_m=gap, speed_m_s=speed):
            edging = f", approaching at {speed:g} m/s" if how == "creep" and speed else ""
            return f"{uav} waits for {leader} to pass first ({gap:.0f} m short){edging}"
        case WaitOver(uav_id=uav):
            return f"{uav} flies on"
        case LeadTaken(uav_id=uav, past_m=past, turned=turned):
            pairs = ", ".join(f"{waits} waits for {first}" for first, waits in turned)
            return f"{uav} stopped {past:.1f} m inside an encounter and goes first: {pairs}"
        case VehicleFinished(uav_id=uav, distance_to_goal_m=d):
            return f"{uav}: landed {d:.1f} m from its goal"
        case Aborted(mode=mode, reason=reason):
            return f"ABORT ({mode}): {reason}"
        case FlightEnded(completed=done):
            return "flight complete" if done else "flight ended early"
    return None


class ProgressDisplay:
    def __init__(self, out: TextIO | None = None) -> None:
        self.out = out or sys.stdout  # the stdout of now, not of when this was imported
        self.live = self.out.isatty()
        self._drawn = 0
        self._last_print = float("-inf")

    def show(self, event: FleetEvent) -> None:
        if isinstance(event, Progress):
            self._table(event)
            return
        line = event_line(event)
        if line is not None:
            self._erase()
            print(line, file=self.out, flush=True)

    def _table(self, event: Progress) -> None:
        if not self.live and event.at - self._last_print < PIPE_EVERY_S:
            return
        self._last_print = event.at
        sep = event.min_separation_m
        lines = [HEADER, *(progress_line(p) for p in event.vehicles)]
        lines.append(f"closest so far: {sep:.1f} m" if sep is not None else "closest so far: -")
        self._erase()
        print("\n".join(lines), file=self.out, flush=True)
        self._drawn = len(lines) if self.live else 0

    def _erase(self) -> None:
        if self._drawn:
            self.out.write(f"\x1b[{self._drawn}F\x1b[J")
            self._drawn = 0

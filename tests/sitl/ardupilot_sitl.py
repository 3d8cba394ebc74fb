"""Real ArduCopter SITL instances for the tests that need the real autopilot.

`ARDUPILOT_SITL=/path/to/arducopter` names a binary built from ArduPilot's sources
(docs/sitl_mock.md says how); without it those tests are skipped, saying so. Each
instance runs from its own working directory (its own eeprom: a fresh vehicle every
time), serves TCP 5760 + 10·i on every interface (we connect to 127.0.0.1 only), and is
stopped by its process id.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest

from gcs.mission.geodesy import GridFrame
from planner.model.scenario import Scenario

ENV = "ARDUPILOT_SITL"
BASE_PORT = 5760
PORT_STRIDE = 10


def binary() -> Path:
    """The SITL binary the environment names, or a skip that says what is missing."""
    value = os.environ.get(ENV)
    if not value:
        pytest.skip(f"real ArduCopter SITL: set {ENV}=/path/to/arducopter (not reachable in CI)")
    path = Path(value)
    if not path.is_file() or not os.access(path, os.X_OK):
        pytest.skip(f"{ENV}={value} is not an executable file")
    return path


def default_params(sitl: Path) -> Path:
    """Tools/autotest/default_params/copter.parm of the checkout the binary was built in
    (build/sitl/bin/arducopter), or $ARDUPILOT_SITL_DEFAULTS."""
    given = os.environ.get("ARDUPILOT_SITL_DEFAULTS")
    path = Path(given) if given else sitl.parents[3] / "Tools/autotest/default_params/copter.parm"
    if not path.is_file():
        pytest.skip(f"no copter.parm at {path}: set ARDUPILOT_SITL_DEFAULTS")
    return path


@dataclass
class Instance:
    index: int
    process: subprocess.Popen[bytes]
    workdir: Path

    @property
    def port(self) -> int:
        return BASE_PORT + PORT_STRIDE * self.index

    @property
    def connection(self) -> str:
        return f"tcp:127.0.0.1:{self.port}"


def homes_at_starts(scenario: Scenario) -> list[tuple[float, float, float]]:
    frame = GridFrame.of(scenario)
    homes = []
    for uav in scenario.uavs:
        lat, lon = frame.to_geodetic(*uav.start)
        homes.append((float(lat), float(lon), frame.alt0))
    return homes


@contextmanager
def instances(
    homes: list[tuple[float, float, float]],
    workdir: Path,
    speedup: float = 1.0,
    params: dict[str, float] | None = None,
) -> Iterator[list[Instance]]:
    """One fresh ArduCopter per home, instance i with system id i + 1, all stopped after.

    `params` (e.g. SIM_WIND_SPD) are set on every instance from boot: a second defaults
    file after copter.parm, so they hold before anything arms."""
    sitl = binary()
    defaults = str(default_params(sitl))
    if params:
        extra = workdir / "extra.parm"
        extra.write_text("".join(f"{name} {value:g}\n" for name, value in params.items()))
        defaults += f",{extra}"
    started: list[Instance] = []
    try:
        for index, (lat, lon, alt) in enumerate(homes):
            port = BASE_PORT + PORT_STRIDE * index
            if _in_use(port):
                pytest.skip(f"TCP port {port} is in use: another SITL is running")
            home = workdir / f"sitl{index}"
            home.mkdir(parents=True)
            command = [
                str(sitl), "--model", "+", "--speedup", f"{speedup:g}",
                "--defaults", defaults, f"-I{index}", "--sysid", str(index + 1),
                "--home", f"{lat:.7f},{lon:.7f},{alt:.2f},0",
            ]  # fmt: skip
            log = (home / "sitl.log").open("wb")
            process = subprocess.Popen(command, cwd=home, stdout=log, stderr=subprocess.STDOUT)
            started.append(Instance(index, process, home))
        for instance in started:
            _wait_listening(instance)
        yield started
    finally:
        for instance in started:
            stop_process(instance.process)


def _in_use(port: int) -> bool:
    with socket.socket() as probe:
        return probe.connect_ex(("127.0.0.1", port)) == 0


def _wait_listening(instance: Instance, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while not _in_use(instance.port):
        if instance.process.poll() is not None:
            log = (instance.workdir / "sitl.log").read_text(errors="replace")[-2000:]
            raise RuntimeError(f"SITL {instance.index} exited: {log}")
        if time.monotonic() > deadline:
            raise TimeoutError(f"SITL {instance.index} did not listen on {instance.port}")
        time.sleep(0.1)


def stop_process(process: subprocess.Popen) -> None:
    """By its process id: SIGTERM, then SIGKILL if it will not go."""
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=5)

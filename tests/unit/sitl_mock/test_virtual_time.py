"""The virtual-time loop: the one clock a simulated flight runs on."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from sitl_mock import Simulator, VehicleConfig
from sitl_mock.virtual_time import EXECUTOR_DELAY_S, VirtualTimeLoop, run_virtual


def test_an_hour_of_sleeping_takes_no_real_time() -> None:
    async def main() -> tuple[float, list[float]]:
        loop = asyncio.get_running_loop()

        async def wake(after: float) -> float:
            await asyncio.sleep(after)
            return loop.time()

        woke = await asyncio.gather(wake(3600.0), wake(1.5), wake(60.0))
        return loop.time(), list(woke)

    started = time.process_time()
    now, woke = run_virtual(main())
    assert (now, woke) == (3600.0, [3600.0, 1.5, 60.0])
    assert time.process_time() - started < 5.0  # no busy loop through an hour of timers


def test_a_timeout_fires_at_its_virtual_moment() -> None:
    async def main() -> float:
        loop = asyncio.get_running_loop()
        with pytest.raises(TimeoutError):
            async with asyncio.timeout(42.0):
                await asyncio.Event().wait()
        return loop.time()

    assert run_virtual(main(), start=100.0) == 142.0


def test_executor_work_runs_at_once_and_takes_no_virtual_time() -> None:
    """A storage write or a plan handed to an executor runs on the loop's thread, taking
    the loop's executor delay of virtual time however long it takes in real time, and its
    outcome (a result or an exception) arrives where a thread's would."""

    def slow(fail: bool) -> str:
        time.sleep(0.05)
        if fail:
            raise ValueError("refused")
        return "stored"

    async def main() -> tuple[str, str, float]:
        loop = asyncio.get_running_loop()
        ticker = asyncio.ensure_future(asyncio.sleep(0.01))  # a timer due very soon
        stored = await loop.run_in_executor(None, slow, False)
        with pytest.raises(ValueError) as refused:
            await asyncio.to_thread(slow, True)
        at = loop.time()
        await ticker
        return stored, str(refused.value), at

    assert run_virtual(main()) == ("stored", "refused", 2 * EXECUTOR_DELAY_S)


def test_the_same_program_replays_the_same_interleaving() -> None:
    async def main() -> list[tuple[float, str]]:
        loop = asyncio.get_running_loop()
        trace: list[tuple[float, str]] = []

        async def worker(name: str, period: float) -> None:
            for _ in range(20):
                await asyncio.sleep(period)
                trace.append((loop.time(), name))

        await asyncio.gather(worker("a", 0.3), worker("b", 0.7), worker("c", 0.1))
        return trace

    assert run_virtual(main()) == run_virtual(main())


def test_simulated_vehicles_run_on_the_loop_clock_through_in_memory_ports() -> None:
    """Ten seconds of a vehicle's life: its heartbeats arrive once a second of the
    virtual clock through an in-memory port, and the simulation is at ten seconds."""

    async def main() -> tuple[float, int]:
        sim = Simulator([VehicleConfig(sysid=1, transport="memory")])
        await sim.start()
        port = sim.memory_port(1)
        heard: list[bytes] = []
        port.set_receiver(heard.append)
        await asyncio.sleep(10.0)
        await sim.stop()
        return sim.sim_time, len(heard)

    sim_time, packets = run_virtual(main())
    assert sim_time == pytest.approx(10.0, abs=0.021)
    assert packets >= 10  # at least one heartbeat a second


def test_a_loop_with_nothing_scheduled_waits_for_other_threads() -> None:
    async def main() -> str:
        loop = asyncio.get_running_loop()
        answer: asyncio.Future[str] = loop.create_future()
        threading.Timer(0.05, lambda: loop.call_soon_threadsafe(answer.set_result, "woken")).start()
        return await answer

    loop = VirtualTimeLoop()
    try:
        assert loop.run_until_complete(main()) == "woken"
        assert loop.time() == 0.0
    finally:
        loop.close()

"""The planning engine: one UAV's path changes at a time, as a flow says.

`Engine.replan` is one run of the black hole (eq. 8): the UAV's search against the
others held fixed, its result kept only if it is better and the exact check agrees.
`Engine.adopt` takes a flight made elsewhere (the anytime flow's safe start). Every
change goes through the conflict table, and every fleet that passes the exact check is
remembered (`record_if_safe`). Where the flows differ, `flow` decides
(`planner.flows.policies`).
"""

from __future__ import annotations

from dataclasses import dataclass

from planner.check.safety import cell_conflicts
from planner.flows import search_costs as costs
from planner.flows.planning import Best, Map, Phase, PlanningState, PlanProgress
from planner.flows.policies import Flow
from planner.flows.run_stop import RunStop
from planner.geometry.path_encoding import DetourEncoding
from planner.model.trajectory import Trajectory
from planner.optimizers import Progress
from planner.search.black_hole import search_path, wait_probe


@dataclass
class Engine:
    state: PlanningState
    flow: Flow

    def replan(self, uav: str, world: Map, phase: Phase, share: float = float("inf")) -> bool:
        """One optimizer run for `uav`, of at most `share` seconds; keeps the new path if it
        costs less and the exact check finds no new conflict. True if kept."""
        state, flow = self.state, self.flow
        encoding = flow.encoding(state, uav, world)
        if encoding is None:
            return False
        corridor = flow.corridor(encoding)
        search = costs.search(state, flow, uav, world, encoding.region(), corridor=corridor)
        before = costs.current_cost(state, flow, uav, world)
        if self.probing(phase) and isinstance(encoding, DetourEncoding):
            probe = wait_probe(encoding, search)
            state.nfe += probe.evaluations
            if probe.safe and probe.cost < before and self.keep(uav, probe.trajectory, phase):
                return True
        # The others' costs leave out their conflicts with `uav`: its own cost counts them.
        others = costs.others_cost(state, flow, uav, world)
        state.runs += 1
        run = state.runs
        # Making a UAV safe needs no polish: once its best is safe the run may end soon.
        resolving = phase is not Phase.IMPROVEMENT and state.settings.objective == "qos"
        stop = RunStop(
            state.budget,
            flow.patience(state.settings, phase),
            safe_below=state.penalty(world) if resolving else None,
        )
        ends = state.budget.elapsed() + share

        def on_iteration(p: Progress) -> bool:
            cost = state.scale * (others + min(p.best_cost, before))
            state.history.append(cost)
            state.iterations_run += 1
            self.report(run, uav, phase, p.iteration, p.iterations, cost)
            return stop(p.best_cost) or state.budget.elapsed() >= ends

        outcome = search_path(
            encoding,
            search,
            algorithm=state.settings.algorithm,
            population=state.settings.population,
            iterations=flow.iterations(state.settings, phase),
            rng=state.rng,
            on_iteration=on_iteration,
        )
        state.nfe += outcome.result.nfe
        if stop.reason == "budget" or state.budget.expired():
            state.stopped_by_budget = True
        state.converged_runs += stop.reason == "converged"
        if not flow.better(state, uav, outcome.trajectory, outcome.cost, before, phase):
            return False
        radius = state.specs[uav].radius
        if cell_conflicts(uav, outcome.trajectory, radius, world.blocked):
            return False  # the search reads clearance from a raster; the exact check decides
        return self.keep(uav, outcome.trajectory, phase)

    def probing(self, phase: Phase) -> bool:
        """A hover is tried before a search when a UAV must be made safe, if an
        improvement phase will shorten it later."""
        return self.flow.probes and phase is not Phase.IMPROVEMENT

    def keep(self, uav: str, trajectory: Trajectory, phase: Phase) -> bool:
        """`uav` flies `trajectory` (in the flow's stored form) from now on, unless
        (improving or probing) the exact check finds more conflicts for it than before,
        or it enters a blocked cell."""
        state = self.state
        spec = state.specs[uav]
        trajectory = self.flow.stored(trajectory, spec.speed)
        if cell_conflicts(uav, trajectory, spec.radius, state.table.blocked):
            return False
        strict = phase is Phase.IMPROVEMENT or self.probing(phase)
        allowed = len(state.table.collision_paths(uav)) if strict else None
        return self.change(uav, trajectory, phase, allowed)

    def adopt(self, uav: str, trajectory: Trajectory, phase: Phase) -> bool:
        """`uav` flies `trajectory` (as the plan will store it) if the exact check finds
        it in no conflict at all."""
        state = self.state
        trajectory = trajectory.quantised(state.specs[uav].speed)
        if cell_conflicts(uav, trajectory, state.specs[uav].radius, state.table.blocked):
            return False
        return self.change(uav, trajectory, phase, allowed=0)

    def change(self, uav: str, trajectory: Trajectory, phase: Phase, allowed: int | None) -> bool:
        """`uav` flies `trajectory`, unless it then has more than `allowed` conflicts by the
        exact check (None: any number). The callers have found `trajectory` in no blocked
        cell of the table's map, so the table is told so rather than count again."""
        state = self.state
        old, old_hits = state.paths[uav], state.table.cell_hits[uav]
        state.paths[uav] = trajectory
        state.table.update(uav, trajectory, cell_hits=0)
        if allowed is not None and len(state.table.collision_paths(uav)) > allowed:
            state.paths[uav] = old  # cheaper by the sampled cost, but not by the exact check
            state.table.update(uav, old, cell_hits=old_hits)
            return False
        state.replans.setdefault(uav, []).append(phase.value)
        self.record_if_safe()
        return True

    def record_if_safe(self) -> None:
        """If the fleet as it stands passes the exact check, remember it (the first time,
        and whenever it is the cheapest yet)."""
        state = self.state
        if self.flow.fleet_passes(state):
            self.record(state.paths, state.replans)

    def record(self, paths: dict[str, Trajectory], replans: dict[str, list[str]]) -> None:
        """Remember a safe fleet: the first one, and whenever it is the cheapest yet."""
        state = self.state
        cost = state.fleet_cost(paths)
        if state.first_safe_s is None:
            state.first_safe_s, state.first_safe_cost = state.budget.elapsed(), cost
        if state.best is None or cost < state.best.cost:
            state.best = Best(dict(paths), {u: list(r) for u, r in replans.items()}, cost)

    def step(self, uav: str, phase: Phase, world: Map) -> None:
        """One change made without the optimizer, as a run of one iteration, for the
        history and the progress callback (so a service's job shows the safe start)."""
        state = self.state
        state.runs += 1
        state.iterations_run += 1
        cost = costs.table_cost(state, world)
        state.history.append(cost)
        self.report(state.runs, uav, phase, 1, 1, cost)

    def report(
        self, run: int, uav: str, phase: Phase, iteration: int, iterations: int, cost: float
    ) -> None:
        state = self.state
        if state.progress is None:
            return
        best = None if state.best is None else state.best.cost
        state.progress(
            PlanProgress(
                run,
                uav,
                phase.value,
                iteration,
                iterations,
                cost,
                elapsed_s=state.budget.elapsed(),
                budget_percent=state.budget.percent(),
                best_cost=best,
                first_safe_s=state.first_safe_s,
            )
        )

"""CPU per fuzzed flight of two source trees, the same seeds flown alternately in one run.

    git worktree add /tmp/before <commit>
    python bench/fuzz_cpu.py /tmp/before . --seeds 1000:1008 --rounds 2

One worker process per tree (this interpreter, the tree first on its path) flies each
seed in turn, the trees' order swapped every round, so that a busy machine slows both
alike; each flight's process time is taken inside its worker, after a first flight that
pays for the imports. Temporary files go to /dev/shm when it exists, as the test suite
has them (tests/conftest.py). Prints each seed's median per tree and the mean over seeds.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

WORKER = """
import sys, time
from tests.fuzz.runner import fly_seed
for line in sys.stdin:
    seed = int(line)
    started = time.process_time()
    report = fly_seed(seed)
    print(f"cpu {seed} {time.process_time() - started:.4f} {report.outcome}", flush=True)
"""


class Worker:
    """One tree's flights, one seed at a time."""

    def __init__(self, tree: Path) -> None:
        env = dict(os.environ, PYTHONPATH=str(tree))
        if Path("/dev/shm").is_dir() and "TMPDIR" not in os.environ:
            env["TMPDIR"] = "/dev/shm"
        self.process = subprocess.Popen(
            [sys.executable, "-c", WORKER],
            cwd=tree,
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )

    def fly(self, seed: int) -> float:
        """The flight's process time in seconds."""
        assert self.process.stdin is not None and self.process.stdout is not None
        self.process.stdin.write(f"{seed}\n")
        self.process.stdin.flush()
        for line in self.process.stdout:  # the service prints its URLs on stdout too
            if line.startswith(f"cpu {seed} "):
                return float(line.split()[2])
        raise RuntimeError(f"the worker stopped during seed {seed}")

    def close(self) -> None:
        assert self.process.stdin is not None
        self.process.stdin.close()
        self.process.wait()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("before", type=Path, help="the tree measured first in round 1")
    parser.add_argument("after", type=Path)
    parser.add_argument("--seeds", default="1000:1008", help="A:B, or a comma-separated list")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args(argv)
    if ":" in args.seeds:
        first, last = (int(x) for x in args.seeds.split(":"))
        seeds = list(range(first, last))
    else:
        seeds = [int(x) for x in args.seeds.split(",")]
    trees = {"before": args.before.resolve(), "after": args.after.resolve()}
    workers = {name: Worker(tree) for name, tree in trees.items()}
    for worker in workers.values():
        worker.fly(seeds[0])  # imports, the first app: paid once by either
    cpu: dict[str, dict[int, list[float]]] = {name: {s: [] for s in seeds} for name in trees}
    for round_ in range(args.rounds):
        order = ["before", "after"] if round_ % 2 == 0 else ["after", "before"]
        for seed in seeds:
            for name in order:
                cpu[name][seed].append(workers[name].fly(seed))
    for worker in workers.values():
        worker.close()
    medians = {name: [statistics.median(cpu[name][s]) for s in seeds] for name in trees}
    for seed, before, after in zip(seeds, medians["before"], medians["after"], strict=True):
        print(f"seed {seed}: before {before:.2f} s, after {after:.2f} s ({after / before:.2f}x)")
    mean = {name: statistics.fmean(values) for name, values in medians.items()}
    print(
        f"CPU per flight over {len(seeds)} seeds, {args.rounds} rounds: before "
        f"{mean['before']:.3f} s, after {mean['after']:.3f} s "
        f"({mean['after'] / mean['before']:.3f}x)"
    )


if __name__ == "__main__":
    main()

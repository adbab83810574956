"""CPU seconds a forked learner spends on its first reply after a comparison (its first GP fit), with
the forkserver's preload as ``app.learning.worker.PRELOAD`` has it, and without the module torch
imports at a process's first fit (``torch.fx.experimental.symbolic_shapes``, through
``torch.broadcast_shapes``; with it sympy), as before.

Each variant runs in a process of its own (a forkserver's preload is fixed once it has started),
which starts ``--learners`` learners one after another, as ``serve`` does for its participants and a
session does when its learner is restarted. Each learner gives its first θ, then fits on two
interactions and their comparison; the figure is the worker's own user + system time from /proc,
read before it is closed. The variants alternate ``--runs`` times; printed are the medians over all
learners of each variant and their ratio (before / now).

Usage: ``.venv/bin/python benchmarks/learner_first_fit.py [--learners 4] [--runs 2]``
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))  # the suite's support package
# the checkout before tests/, whose robot_io/ folder would pass for the robot_io package
sys.path.insert(0, str(Path(__file__).parents[1]))

from support.processes import cpu_seconds

TABLE_I = {"a": (1.0, 10.0), "delta": (-1.0, 1.0), "k": (0.01, 15.0)}


def learners_cpu(learners: int) -> list[float]:
    """In this process: the CPU seconds of each of ``learners`` learners up to its first fit's reply."""
    from app.learning.config import LearnerConfig
    from app.learning.models import Comparison, Interaction, ParameterBox
    from app.learning.worker import LearnerClient

    config = LearnerConfig(box=ParameterBox.from_bounds(TABLE_I), seed=7)
    spent = []
    for _ in range(learners):
        with LearnerClient(config) as client:
            client.submit()
            first = client.get(timeout=600.0)
            client.submit([Interaction(interaction_id="1", theta=first.theta)])
            second = client.get(timeout=600.0)
            client.submit([Interaction(interaction_id="2", theta=second.theta)],
                          [Comparison(winner="2", loser="1")])
            client.get(timeout=600.0)
            spent.append(cpu_seconds(client._process.pid))
    return spent


def run_variant(before: bool, learners: int) -> list[float]:
    """The learners' CPU seconds, measured in a fresh process."""
    command = [sys.executable, __file__, "--measure", str(learners)] + (["--before"] if before else [])
    done = subprocess.run(command, capture_output=True, text=True, check=True, timeout=1800)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--learners", type=int, default=4)
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--measure", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--before", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure is not None:
        if args.before:
            from app.learning import worker

            worker.PRELOAD = ["app.learning.learner"]  # the learner alone, as before
        print(json.dumps(learners_cpu(args.measure)))
        return
    now: list[float] = []
    before: list[float] = []
    for _ in range(args.runs):  # alternated: a change of the machine's load touches both
        now += run_variant(False, args.learners)
        before += run_variant(True, args.learners)
    median_now, median_before = statistics.median(now), statistics.median(before)
    print(f"learner CPU to its first fit's reply, median of {len(now)} learners each:")
    print(f"  preload now:                               {median_now:.2f} s")
    print(f"  without torch's first-fit module (before): {median_before:.2f} s")
    print(f"  saved per learner {median_before - median_now:.2f} s (ratio {median_before / median_now:.2f}×)")


if __name__ == "__main__":
    main()

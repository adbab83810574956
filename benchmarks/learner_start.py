"""How long a new learner takes to give its first θ: ``LearnerClient(...)`` → the first reply.

A session starts a learner when a participant is created or resumed, and again when a worker died.
This starts ``--learners`` learners one after another in one process (as ``serve`` does for its
participants) with each start method — ``spawn`` (a fresh interpreter imports torch, GPyTorch and
BoTorch every time; the method before the forkserver) and ``forkserver`` (``app.learning.worker``'s
default: the server imports them once, every worker is forked from it) — and prints, per method,
the first learner's time, the median and max of the others, and the ratio of the medians
(spawn / forkserver) of this run. (No CPU time: the forkserver's workers are not this process's
children, so the process's own counters cannot see them.)

Usage: ``.venv/bin/python benchmarks/learner_start.py [--learners 6]``
"""

from __future__ import annotations

import argparse
import statistics
import time

from app.learning.config import LearnerConfig
from app.learning.models import ParameterBox
from app.learning.worker import LearnerClient

TABLE_I = {"a": (1.0, 10.0), "delta": (-1.0, 1.0), "k": (0.01, 15.0)}


def first_reply_s(config: LearnerConfig, start_method: str) -> float:
    """Seconds from creating a learner to its first θ."""
    began = time.perf_counter()
    with LearnerClient(config, start_method=start_method) as client:
        client.submit()
        client.get(timeout=600.0)
        return time.perf_counter() - began


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--learners", type=int, default=6)
    args = parser.parse_args()
    config = LearnerConfig(box=ParameterBox.from_bounds(TABLE_I), seed=1)
    medians = {}
    for method in ("spawn", "forkserver"):
        times = [first_reply_s(config, method) for _ in range(args.learners)]
        medians[method] = statistics.median(times[1:])
        print(f"{method:>10}: first {times[0]:.2f} s, then median {medians[method]:.2f} s, "
              f"max {max(times[1:]):.2f} s ({args.learners - 1} learners)")
    print(f"median after the first, spawn / forkserver: {medians['spawn'] / medians['forkserver']:.1f}x")


if __name__ == "__main__":
    main()

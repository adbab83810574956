"""Latency of the learner worker: "comparisons submitted" → "next θ available" (session view).

A :class:`~app.learning.worker.LearnerClient` (real worker process, session defaults: refit with
warm start after every interaction, 4 restarts × 256 raw samples) is driven through a long
schedule (q = 5) by a simulated participant on Table I's box. Each request carries one new
interaction and its comparisons; the time from ``submit`` to the reply being available to
``poll`` is recorded for the requests whose reply is a new query (fit + acquisition, the slow
case), grouped by the number n of unique points in the model (n ≈ 10: 8–12, n ≈ 30: 28–32).

Goal (issue 3): median < 0.5 s and p95 < 1.5 s at n = 30.
Usage: ``.venv/bin/python benchmarks/learner_latency.py [--runs 4]``
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

from app.learning.config import AcquisitionName, LearnerConfig
from app.learning.models import Interaction, ParameterBox, Placement, SlotKind
from app.learning.planner import BatchSchedule
from app.learning.scale import comparisons_for_newest
from app.learning.simulation import scale_position
from app.learning.worker import LearnerClient

TABLE_I = {"a": (1.0, 10.0), "delta": (-1.0, 1.0), "k": (0.01, 15.0)}
WINDOWS = {10: range(8, 13), 30: range(28, 33)}


def one_run(acquisition: AcquisitionName, seed: int) -> dict[int, list[float]]:
    box = ParameterBox.from_bounds(TABLE_I)
    config = LearnerConfig(box=box, acquisition=acquisition, seed=seed,
                           schedule=BatchSchedule(n_initial=5, q=5, n_unique=34))
    target = np.random.default_rng(seed).uniform(size=3)
    latencies: dict[int, list[float]] = {n: [] for n in WINDOWS}
    with LearnerClient(config) as client:
        client.submit()
        suggestion = client.get(timeout=60.0)
        placements: list[Placement] = []
        while suggestion.theta is not None:
            if suggestion.slot.position == 1:
                placements = []
            iid = str(suggestion.slot.index + 1)
            y = float(np.linalg.norm(target - np.array(box.to_unit(suggestion.theta))))
            placements.append(Placement(interaction_id=iid, position=scale_position(y)))
            start = time.monotonic()
            client.submit([Interaction(interaction_id=iid, theta=suggestion.theta)],
                          comparisons_for_newest(placements))
            while (reply := client.poll()) is None:
                time.sleep(0.001)
            elapsed = time.monotonic() - start
            n = reply.fit.n_points
            for window, members in WINDOWS.items():
                if reply.slot.kind is SlotKind.QUERY and n in members:
                    latencies[window].append(elapsed)
            suggestion = reply
    return latencies


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, math.ceil(q * len(ordered)) - 1)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=4, help="sessions per acquisition")
    args = parser.parse_args()
    print("submit → next θ available, worker process, query replies only (fit + acquisition)")
    for acquisition in (AcquisitionName.QNEI, AcquisitionName.EUBO):
        pooled: dict[int, list[float]] = {n: [] for n in WINDOWS}
        for run in range(args.runs):
            for n, values in one_run(acquisition, seed=100 + run).items():
                pooled[n].extend(values)
        for n, values in pooled.items():
            median, p95 = statistics.median(values), percentile(values, 0.95)
            verdict = ("goal met" if median < 0.5 and p95 < 1.5 else "goal MISSED") if n == 30 \
                else ""
            print(f"{acquisition.value:>5} n≈{n}: median {median:.3f} s, p95 {p95:.3f} s, "
                  f"max {max(values):.3f} s over {len(values)} requests  {verdict}")


if __name__ == "__main__":
    main()

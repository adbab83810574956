"""The learner's positive control: the acquisitions against the Sobol baseline on the same seeds.

Issue 14's goals, run as a study (they were tests until the suite had to fit in 12 minutes; the code
path they drive stays tested in tests/learning/test_study.py on a small fixed-seed study):

* σ = 0.03, qNEI (q = 5): the final inference distance u(θ*) is at most 0.7× Sobol's and the paired
  95 % CI of the per-trial difference excludes 0 (the learner learns);
* σ = 0.05, the paper's noise, with the default θ* strategy: EUBO (q = 2) and qNEI (q = 5) each at
  most 0.85× Sobol's, the paired CI excluding 0.

Every condition sees the same targets and noise (benchmark-pl's study seed), Sobol's trials run once
and are shared. Prints per goal the mean final distances, their ratio, the paired CI of the
difference and whether the goal holds; exits 1 if any does not. Resumable (the CSVs under --out).

Usage: ``nice -n 19 .venv/bin/python benchmarks/learner_beats_sobol.py [--trials 16] [--workers 2]``
(16 trials, seed 7: what the tests ran, ≈ 6 min of CPU; docs/learning.md has N = 200).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from app.learning.cluster import dask_client
from app.learning.config import AcquisitionName
from app.learning.simulated_study import final_distances, t_half_width
from app.learning.simulation import StudyCondition

#: (acquisition, q, σ, the largest ratio to Sobol's mean final distance that meets the goal)
GOALS = ((AcquisitionName.QNEI, 5, 0.03, 0.7),
         (AcquisitionName.EUBO, 2, 0.05, 0.85),
         (AcquisitionName.QNEI, 5, 0.05, 0.85))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=16)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("out/learner-beats-sobol"))
    args = parser.parse_args()
    met = []
    with dask_client(workers=args.workers) as client:
        for acquisition, q, noise, ratio in GOALS:
            def finals(acq: AcquisitionName, batch: int, noise: float = noise) -> np.ndarray:
                condition = StudyCondition(acquisition=acq, q=batch, noise=noise)
                return np.array(final_distances(condition, trials=args.trials, seed=args.seed,
                                                client=client, out=args.out))

            learned, sobol = finals(acquisition, q), finals(AcquisitionName.SOBOL, 5)
            diff = learned - sobol
            half = t_half_width(list(diff))
            holds = learned.mean() <= ratio * sobol.mean() and diff.mean() + half < 0.0
            met.append(holds)
            print(f"σ = {noise:.2f}  {acquisition.value} q = {q}: u(θ*) {learned.mean():.3f} "
                  f"against Sobol {sobol.mean():.3f} (baseline, same seeds): ratio "
                  f"{learned.mean() / sobol.mean():.2f} (goal ≤ {ratio}); paired difference "
                  f"{diff.mean():+.3f} ± {half:.3f} (goal: CI below 0)  "
                  f"{'met' if holds else 'NOT MET'}", flush=True)
    print(f"{sum(met)} of {len(met)} goals met ({args.trials} trials, seed {args.seed})")
    return 0 if all(met) else 1


if __name__ == "__main__":
    sys.exit(main())

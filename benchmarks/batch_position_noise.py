"""Does weighing comparisons by the noise of eq. (16) help? The same simulated study (benchmark-pl's
code, same study seed: paired targets and noise) with BoTorch's probit, every comparison equally
reliable, and with app.learning.comparison_noise's likelihood (comparisons between batch positions i
and j √((i² + j²)/2) times as noisy).

Prints per σ the final and interaction-15 inference distance u(θ*) of each likelihood (θ* by the
learner's default strategy), the paired 95 % CI of the difference and the oracle distance (best
shown). Resumable (benchmark-pl's CSVs under --out).

Usage: ``nice -n 19 .venv/bin/python benchmarks/batch_position_noise.py --trials 200 --workers 2``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from recommendation_study import mean_ci

from app.learning.cluster import dask_client
from app.learning.config import DEFAULT_RECOMMENDATION, AcquisitionName
from app.learning.simulated_study import TrialStore, run_condition
from app.learning.simulation import StudyCondition


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=200)
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--acq", choices=[a.value for a in AcquisitionName], default="qnei")
    parser.add_argument("--noises", type=float, nargs="+", default=[0.05])
    parser.add_argument("--early", type=int, default=15, help="interaction also reported")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--scheduler", default=None)
    parser.add_argument("--out", type=Path, default=Path("out/batch-position-noise"))
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args()

    print(f"N = {args.trials} paired seeds (study seed {args.seed}), θ* by "
          f"{DEFAULT_RECOMMENDATION.value}; u(θ*) with 95 % CIs")
    print(f"| condition | likelihood | u(θ*) @{args.early} | final u(θ*) | final oracle |")
    print("| --- | --- | --- | --- | --- |")
    with dask_client(args.scheduler, args.workers) as client:
        for noise in args.noises:
            base = StudyCondition(acquisition=AcquisitionName(args.acq), noise=noise)
            curves = {}
            for weighed in (False, True):
                condition = base.with_batch_position_noise(weighed)
                run_condition(condition, trials=args.trials, seed=args.seed, client=client,
                              out=args.out, progress=not args.no_progress)
                stored = TrialStore(args.out / condition.name, condition, args.seed).load()
                ordered = [stored[t] for t in range(args.trials)]
                curves[weighed] = np.array([r.distances for r in ordered])
                oracle = np.array([r.oracle_distances[-1] for r in ordered])
                early, final = curves[weighed][:, args.early - 1], curves[weighed][:, -1]
                cells = [f"{m:.3f} [{lo:.3f}, {hi:.3f}]" for m, lo, hi in
                         (mean_ci(early), mean_ci(final))]
                print(f"| {base.name} | {'batch position' if weighed else 'equal'} | "
                      f"{cells[0]} | {cells[1]} | {oracle.mean():.3f} |")
            for n, label in ((args.early, f"@{args.early}"), (curves[True].shape[1], "final")):
                m, lo, hi = mean_ci(curves[True][:, n - 1] - curves[False][:, n - 1])
                print(f"| {base.name} | batch position − equal, paired, {label} | "
                      f"{m:+.3f} [{lo:+.3f}, {hi:+.3f}] | | |")


if __name__ == "__main__":
    main()

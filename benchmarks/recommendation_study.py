"""Which θ* to recommend under the noise of eq. (16): the recommendation study of docs/learning.md.

Runs qNEI q = 5, EUBO (q = 2) and Sobol at σ = 0, 0.03, 0.05 with ``handover benchmark-pl``'s code
(same study seed, so every condition and strategy sees the same targets and noise: paired seeds),
then prints per condition and strategy the final inference distance u(θ*) with its 95 % CI, the
paired 95 % CI of its difference to today's strategy (in-sample posterior mean), the final oracle
distance, and the ratio to Sobol's distance under the same strategy (paired bootstrap CI).

Resumable (the CSVs under --out); a larger --trials later extends the same study.

Usage: ``nice -n 19 .venv/bin/python benchmarks/recommendation_study.py --trials 200 --workers 1``
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import numpy as np
from scipy import stats

from app.learning.cluster import dask_client
from app.learning.config import AcquisitionName
from app.learning.figures import draw_figure3
from app.learning.models import RecommendationName
from app.learning.simulated_study import TrialStore, run_condition, t_half_width
from app.learning.simulation import StudyCondition

NOISES = (0.05, 0.03, 0.0)  # the noisy conditions first: they decide the default
METHODS = ((AcquisitionName.QNEI, 5), (AcquisitionName.EUBO, 2), (AcquisitionName.SOBOL, 5))
TODAY = RecommendationName.IN_SAMPLE_MEAN


def mean_ci(values: np.ndarray) -> tuple[float, float, float]:
    """Mean and Student-t 95 % CI."""
    mean, half = float(values.mean()), t_half_width(values.tolist())
    return mean, mean - half, mean + half


def ratio_ci(a: np.ndarray, b: np.ndarray, seed: int) -> tuple[float, float, float]:
    """mean(a) / mean(b) with a paired percentile-bootstrap 95 % CI (pairs resampled together)."""
    result = stats.bootstrap((a, b), lambda x, y: x.mean() / y.mean(), paired=True,
                             vectorized=False, n_resamples=2000, method="percentile",
                             random_state=np.random.default_rng(seed))
    ci = result.confidence_interval
    return float(a.mean() / b.mean()), float(ci.low), float(ci.high)


def finals(directory: Path, condition: StudyCondition, seed: int, trials: int
           ) -> dict[str, np.ndarray]:
    """Final distance per trial: every strategy, and ``oracle``."""
    results = TrialStore(directory, condition, seed).load()
    ordered = [results[t] for t in sorted(results) if t < trials]
    out = {s.value: np.array([r.strategy_distances[s][-1] for r in ordered])
           for s in RecommendationName}
    out["oracle"] = np.array([r.oracle_distances[-1] for r in ordered])
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=200)
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--scheduler", default=None)
    parser.add_argument("--out", type=Path, default=Path("out/recommendation"))
    parser.add_argument("--noises", type=float, nargs="+", default=list(NOISES),
                        help="σ values to run and report (default 0.05 0.03 0)")
    parser.add_argument("--no-progress", action="store_true")
    parser.add_argument("--figure", type=Path, default=None,
                        help="PNG: Fig. 3 (inference and oracle curves) of every condition")
    args = parser.parse_args()

    conditions = [StudyCondition(acquisition=acq, q=q, noise=noise, recommendation=TODAY)
                  for noise in args.noises for acq, q in METHODS]
    with dask_client(args.scheduler, args.workers) as client:
        results = [run_condition(condition, trials=args.trials, seed=args.seed, client=client,
                                 out=args.out, progress=not args.no_progress)
                   for condition in conditions]
    if args.figure is not None:
        draw_figure3([r for r in results if r[0].noise == max(args.noises)], args.figure)
    data = {c.name: finals(args.out / c.name, c, args.seed, args.trials) for c in conditions}
    print(f"N = {args.trials} paired seeds (study seed {args.seed}); final interaction; "
          "distances to the target, 95 % CIs")
    print("| condition | strategy | final inference distance | difference to in_sample_mean "
          "(paired) | ratio to Sobol, same strategy (paired) | oracle |")
    print("| --- | --- | --- | --- | --- | --- |")
    for condition in conditions:
        finals_c = data[condition.name]
        sobol = data[f"sobol-q5-s{condition.noise:g}"]
        for strategy in RecommendationName:
            d = finals_c[strategy.value]
            m, lo, hi = mean_ci(d)
            dm, dlo, dhi = mean_ci(d - finals_c[TODAY.value]) if strategy is not TODAY else (
                0.0, 0.0, 0.0)
            diff = "—" if strategy is TODAY else f"{dm:+.3f} [{dlo:+.3f}, {dhi:+.3f}]"
            if condition.acquisition is AcquisitionName.SOBOL:
                ratio = "—"
            else:
                r, rlo, rhi = ratio_ci(d, sobol[strategy.value], args.seed)
                ratio = f"{r:.2f} [{rlo:.2f}, {rhi:.2f}]"
            print(f"| {condition.name} | {strategy.value} | {m:.3f} [{lo:.3f}, {hi:.3f}] | "
                  f"{diff} | {ratio} | {statistics.fmean(finals_c['oracle']):.3f} |")


if __name__ == "__main__":
    main()

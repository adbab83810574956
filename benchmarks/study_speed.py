"""Seconds per simulated trial (Sect. IV): this implementation vs BoTorch's tutorial defaults.

The baseline follows BoTorch's preference-BO tutorial: hyperparameters refitted from scratch after
every interaction, ``optimize_acqf(num_restarts=10, raw_samples=512)`` run to SciPy's default
tolerance, 512 MC samples (qNEI's default sampler), GPyTorch's default lazy kernel evaluation. The
study configuration: warm-started fits, done only before a query (the posterior is updated with
fixed hyperparameters after the other interactions), fewer restarts and raw samples, searches to a
looser tolerance, kernels evaluated directly, and trials in parallel on a local Dask cluster
(``--workers``). Both run the same trials (same targets, same noise), alternating trial by trial
so that a machine that slows down or speeds up during the run burdens both alike; the final
distances are compared per trial. Both recommend θ* by the condition's strategy
(``--recommendation``, default the learner's).

Prints medians, the ratio to the baseline, and the projected time of the full paper study
(six conditions × 500 trials) on this machine from per-condition timings.

Usage: ``.venv/bin/python benchmarks/study_speed.py [--trials 12] [--workers 2]``
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import torch

from app.learning.cli import PAPER_CONDITIONS
from app.learning.cluster import dask_client
from app.learning.config import (
    DEFAULT_RECOMMENDATION,
    AcquisitionName,
    ModelConfig,
    OptimizerConfig,
    RecommendationName,
)
from app.learning.simulated_study import run_condition, summarise, t_half_width
from app.learning.simulation import StudyCondition, TrialResult, run_trial

BASELINE_MODEL = ModelConfig(warm_start=False, lazy_fit=False, lazy_kernels=True)
BASELINE_OPTIMIZER = OptimizerConfig(num_restarts=10, raw_samples=512, mc_samples=512)


def alternating_trials(conditions: list[StudyCondition], seed: int,
                       trials: int) -> list[list[TrialResult]]:
    """Trial t of every condition, then trial t + 1 of every condition, ...: one list per
    condition, so drifts of the machine's speed fall on all of them alike."""
    rows = [[run_trial(c, seed, t) for c in conditions] for t in range(trials)]
    return [list(column) for column in zip(*rows, strict=True)]


def describe(label: str, results: list[TrialResult]) -> tuple[float, str]:
    seconds = [r.seconds for r in results]
    final = summarise(results)[-1]
    median = statistics.median(seconds)
    # linear interpolation between order statistics; with one trial, that trial
    p90 = statistics.quantiles(seconds, n=10, method="inclusive")[-1] if len(seconds) > 1 else median
    return median, (f"{label:>34}: median {median:6.2f} s/trial (p90 "
                    f"{p90:.2f}), final mean distance "
                    f"{final.mean_distance:.3f} [{final.ci_low:.3f}, {final.ci_high:.3f}], "
                    f"success {final.success_rate:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--acq", default="qnei", choices=[a.value for a in AcquisitionName])
    parser.add_argument("--q", type=int, default=5)
    parser.add_argument("--noise", type=float, default=0.05)
    parser.add_argument("--trials", type=int, default=12)
    parser.add_argument("--recommendation", default=DEFAULT_RECOMMENDATION.value,
                        choices=[r.value for r in RecommendationName])
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--workers", type=int, default=2, help="Dask workers for the parallel run")
    parser.add_argument("--project-trials", type=int, default=3,
                        help="trials per paper condition timed for the projection")
    args = parser.parse_args()
    torch.set_num_threads(1)

    ours = StudyCondition(acquisition=args.acq, q=args.q, noise=args.noise,
                          recommendation=args.recommendation)
    baseline = ours.model_copy(update={"model": BASELINE_MODEL, "optimizer": BASELINE_OPTIMIZER})
    print(f"condition {ours.name}, {args.trials} trials, seed {args.seed}, torch single-threaded")
    run_trial(ours, args.seed, 10**6)  # warm-up: the first fit in a process is slow
    # the share of the speed-up that is GPyTorch's kernel evaluation rather than the study preset
    ours_lazy = ours.model_copy(update={"model": ours.model.model_copy(
        update={"lazy_kernels": True})})
    base_results, our_results, lazy_results = alternating_trials([baseline, ours, ours_lazy],
                                                                 args.seed, args.trials)
    base_median, base_line = describe("baseline (tutorial defaults)", base_results)
    our_median, our_line = describe("this implementation, 1 process", our_results)
    lazy_median, lazy_line = describe("the same, lazy kernels", lazy_results)
    print(base_line)
    print(our_line)
    print(lazy_line)
    paired = statistics.median(b.seconds / o.seconds
                               for b, o in zip(base_results, our_results, strict=True))
    print(f"{'speed-up, 1 process':>34}: {base_median / our_median:.2f}x (ratio of medians); "
          f"{paired:.2f}x (median of the per-trial ratios); with lazy kernels "
          f"{base_median / lazy_median:.2f}x")
    # same targets and noise per trial: the paired difference is the sharper comparison
    diffs = [o.distances[-1] - b.distances[-1]
             for o, b in zip(our_results, base_results, strict=True)]
    half, mean = t_half_width(diffs), statistics.fmean(diffs)
    print(f"{'final distance, ours - baseline':>34}: {mean:+.3f} [{mean - half:+.3f}, "
          f"{mean + half:+.3f}] (paired, 95 % CI)")
    with tempfile.TemporaryDirectory() as out:
        start = time.monotonic()
        with dask_client(workers=args.workers) as client:
            run_condition(ours, trials=args.trials, seed=args.seed, client=client, out=Path(out),
                          progress=False)
        wall = (time.monotonic() - start) / args.trials
    print(f"{f'this implementation, --workers {args.workers}':>34}: {wall:6.2f} s/trial wall "
          f"clock (cluster start-up included) -> {base_median / wall:.2f}x the baseline")

    total = 0.0
    for acq, q, noise in PAPER_CONDITIONS[:6]:
        condition = StudyCondition(acquisition=acq, q=q, noise=noise)
        timed = alternating_trials([condition], args.seed + 1, args.project_trials)[0]
        median = statistics.median(r.seconds for r in timed)
        total += 500 * median
        print(f"{condition.name:>34}: median {median:.2f} s/trial")
    print(f"projected full study (6 conditions x 500 trials): {total / 3600:.2f} h in 1 process, "
          f"{total / 3600 / args.workers:.2f} h with --workers {args.workers}")


if __name__ == "__main__":
    main()

"""``handover benchmark-pl``: the simulated preference-learning study of Sect. IV (and Fig. 3);
``handover pilot``: whole simulated studies and the power of the paper's sign test."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

from app.learning.config import DEFAULT_RECOMMENDATION, AcquisitionName, StoppingRule
from app.learning.models import RecommendationName, TieHandling

#: The six conditions of Sect. IV (qNEI q = 2, qNEI q = 5, EUBO; σ = 0 and 0.05) plus the Sobol
#: baseline. EUBO compares one new point with θ*, i.e. batches of q = 2.
PAPER_CONDITIONS: tuple[tuple[AcquisitionName, int, float], ...] = (
    *((acq, q, noise)
      for noise in (0.0, 0.05)
      for acq, q in ((AcquisitionName.QNEI, 2), (AcquisitionName.QNEI, 5),
                     (AcquisitionName.EUBO, 2))),
    (AcquisitionName.SOBOL, 5, 0.05),
)


def _spread(text: str) -> float | str:
    """``--spread``: a number in [0, 1] or ``paper``."""
    from app.learning.paper_population import PAPER_POPULATION

    if text == PAPER_POPULATION:
        return text
    try:
        return _bounded(float, 0.0, 1.0)(text)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"{exc}; allowed: a number in [0, 1] or "
                                         f"{PAPER_POPULATION!r}") from None


def _bounded(kind: type[int] | type[float], low: float, high: float) -> Callable[[str], float]:
    """An argparse type accepting ``kind`` values in [low, high], naming the range otherwise."""

    def parse(text: str) -> float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not a{'n integer' if kind is int else ' number'}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(
                f"{value} is outside the allowed range [{low}, {high}]")
        return value

    return parse


def add_cluster_options(parser: argparse.ArgumentParser) -> None:
    """``--workers`` / ``--scheduler``: where the trials run (Dask, :mod:`app.learning.cluster`)."""
    parser.add_argument("--workers", "--jobs", type=_bounded(int, 1, 64), default=1,
                        help="worker processes of the local Dask cluster, one torch thread each "
                        "(default 1)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="a running Dask scheduler, e.g. tcp://lab-server:8786, instead of a "
                        "local cluster (--workers is then ignored)")


def add_shared_options(parser: argparse.ArgumentParser, *, noise: float, out: str,
                       figure: str) -> None:
    """The options ``benchmark-pl`` and ``pilot`` share: method, noise, seed, where to run,
    where to write, how to report."""
    parser.add_argument("--acq", choices=[a.value for a in AcquisitionName], default="qnei",
                        help="acquisition function (default: qnei, the paper's)")
    parser.add_argument("--noise", type=_bounded(float, 0.0, 1.0), default=noise,
                        help=f"σ of y = u + j·N(0, σ²), eq. (16) (default {noise:g})")
    parser.add_argument("--seed", type=_bounded(int, 0, 2**62), default=0, help="seed")
    parser.add_argument("--initial", type=_bounded(int, 1, 50), default=5,
                        help="initial Sobol interactions (default 5, the paper's)")
    parser.add_argument("--recommendation", choices=[r.value for r in RecommendationName],
                        default=DEFAULT_RECOMMENDATION.value,
                        help=f"θ* strategy (default {DEFAULT_RECOMMENDATION.value})")
    parser.add_argument("--batch-position-noise", action="store_true",
                        help="the learner weighs each comparison by the noise of eq. (16) at the "
                        "batch positions it compares (default: every comparison equally)")
    parser.add_argument("--tie", type=_bounded(float, 0.0, 1.0), default=0.0,
                        help="the simulated participant says 'equal' when two impressions of a "
                        "batch differ by less than this (default 0: never)")
    parser.add_argument("--ties", choices=[t.value for t in TieHandling], default="drop",
                        help="what the learner does with 'equal': drop (the paper's rule, default) "
                        "or model (a tie in the likelihood, docs/learning.md)")
    parser.add_argument("--coactive", action="store_true",
                        help="after each placement the simulated participant may hint which way "
                        "the 2nd or 3rd parameter (δ, k) should have moved, each hint one more "
                        "comparison (docs/learning.md, 'Coactive hints'; default: no hints)")
    add_cluster_options(parser)
    parser.add_argument("--out", type=Path, default=Path(out),
                        help=f"output folder, resumed from (default {out})")
    parser.add_argument("--figure", type=Path, default=None, help=figure)
    parser.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``benchmark-pl`` to the ``handover`` command."""
    parser = subparsers.add_parser(
        "benchmark-pl", help="simulated preference-learning study (paper Sect. IV, Fig. 3)",
        description="The simulated preference-learning study of the paper's Sect. IV (Fig. 3): "
                    "each condition's learner against a simulated participant, trial after trial; "
                    "the results folder is resumed from when run again.")
    parser.add_argument("--q", type=_bounded(int, 2, 25), default=5,
                        help="interactions per batch, θ* included (default 5; EUBO: 2 is pairwise)")
    parser.add_argument("--trials", type=_bounded(int, 1, 100_000), default=500,
                        help="trials per condition (default 500, the paper's)")
    parser.add_argument("--queries", type=_bounded(int, 2, 200), default=25,
                        help="unique points shown per trial, initial ones included (default 25)")
    parser.add_argument("--paper", action="store_true",
                        help="run the six paper conditions plus sobol and draw Fig. 3")
    add_shared_options(parser, noise=0.0, out="out/benchmark-pl",
                       figure="PNG path for Fig. 3 with --paper (default OUT/figure3.png)")
    parser.set_defaults(func=run)
    register_pilot(subparsers)


def register_pilot(subparsers: argparse._SubParsersAction) -> None:
    """Add ``pilot`` to the ``handover`` command."""
    parser = subparsers.add_parser(
        "pilot", help="simulate whole studies: validation scores and sign-test power",
        description="Simulate M studies of the paper's protocol (5 initial + 4 batches of 5 + 1 "
        "best + 4 validation pairs) with simulated participants and report the validation "
        "scores and the power of the sign test at α = 0.05 and 0.001, with 95 %% CIs.")
    parser.add_argument("--participants", type=_bounded(int, 1, 1000), default=8,
                        help="participants per scenario (default 8, the paper's)")
    parser.add_argument("--scenarios", type=_bounded(int, 1, 20), default=2,
                        help="scenarios (default 2, the paper's)")
    parser.add_argument("--studies", type=_bounded(int, 1, 100_000), default=50,
                        help="M, simulated studies (default 50)")
    parser.add_argument("--batches", type=_bounded(int, 1, 50), default=4,
                        help="learning batches (default 4, the paper's)")
    parser.add_argument("--batch-size", type=_bounded(int, 2, 25), default=5,
                        help="interactions per learning batch, θ* included (default 5)")
    parser.add_argument("--spread", type=_spread, default=None,
                        help="spread of the participants' optima around a scenario's shared one "
                        "(unit-cube sd, 0 to 1), or 'paper': optima resampled from the θ* of "
                        "Tables II–III; default: uniform optima, no shared structure")
    parser.add_argument("--stop-when-settled", type=_bounded(float, 0.5, 1.0), default=None,
                        metavar="THRESHOLD", help="end learning after a batch (at least 2) once "
                        "the learner is this sure that the best θ would be preferred to θ* at "
                        "most 60 %% of the time, as [protocol] stop_when_settled does (default: "
                        "the fixed schedule)")
    add_shared_options(parser, noise=0.05, out="out/pilot",
                       figure="PNG of scores and power (default OUT/pilot.png)")
    parser.set_defaults(func=run_pilot_command)


def run_pilot_command(args: argparse.Namespace) -> int:
    """Run the pilot; print the power table (or JSON) and draw the figure."""
    from app.learning.cluster import dask_client
    from app.learning.figures import draw_pilot
    from app.learning.pilot import PilotConfig, run_pilot
    from app.learning.planner import BatchSchedule

    schedule = BatchSchedule(n_initial=args.initial, q=args.batch_size,
                             n_unique=args.initial + args.batches * (args.batch_size - 1))
    config = PilotConfig(studies=args.studies, participants=args.participants,
                         scenarios=args.scenarios, noise=args.noise, spread=args.spread,
                         schedule=schedule,
                         acquisition=AcquisitionName(args.acq),
                         recommendation=RecommendationName(args.recommendation), seed=args.seed,
                         batch_position_noise=args.batch_position_noise, tie=args.tie,
                         ties=TieHandling(args.ties), coactive=args.coactive,
                         stopping=None if args.stop_when_settled is None else
                         StoppingRule(threshold=args.stop_when_settled))
    with dask_client(args.scheduler, args.workers) as client:
        report = run_pilot(config, client=client, out=args.out, progress=not args.no_progress)
    figure = draw_pilot(report, args.figure or args.out / "pilot.png")
    report = report.model_copy(update={"figure": str(figure)})
    if args.json:
        print(json.dumps(report.model_dump(mode="json"), indent=2))
    else:
        n = config.scenarios * config.participants
        print(f"{config.studies} simulated studies, {n} participants each "
              f"({config.participants} per scenario), σ = {config.noise:g}")
        print("validation scores: " + ", ".join(f"{k} {v:.2f}"
                                                for k, v in report.score_distribution.items())
              + f" (mean {report.mean_score:.2f})")
        print(f"learning used a median of {report.median_learning_interactions:g} interactions "
              f"of {schedule.n_interactions}; mean u(θ*) {report.mean_final_distance:.3f}"
              + (f"; {report.mean_hints:.1f} hints per participant" if config.coactive else ""))
        for p in report.power:
            print(f"sign test power at α = {p.alpha:g}: {p.power:.2f} [{p.ci_low:.2f}, "
                  f"{p.ci_high:.2f}] ({p.significant} of {p.studies} studies)")
        print(f"figure written to {figure}")
    sys.stdout.flush()
    return 0


def run(args: argparse.Namespace) -> int:
    """Run the study as the arguments say; print a table (or JSON) of the final figures."""
    from app.learning.cluster import dask_client
    from app.learning.simulated_study import run_condition
    from app.learning.simulation import StudyCondition

    if args.initial > args.queries:
        raise ValueError(f"--initial = {args.initial} must not exceed --queries = {args.queries}")
    specs = PAPER_CONDITIONS if args.paper else ((AcquisitionName(args.acq), args.q, args.noise),)
    results = []
    with dask_client(args.scheduler, args.workers) as client:
        for acq, q, noise in specs:
            condition = StudyCondition(acquisition=acq, q=q, noise=noise, n_unique=args.queries,
                                       n_initial=args.initial,
                                       recommendation=RecommendationName(args.recommendation),
                                       coactive=args.coactive).with_batch_position_noise(args.batch_position_noise
                                                                   ).with_ties(args.tie,
                                                                               TieHandling(args.ties))
            results.append(run_condition(condition, trials=args.trials, seed=args.seed,
                                         client=client, out=args.out,
                                         progress=not args.no_progress))
    figure = None
    if args.paper:
        from app.learning.figures import draw_figure3

        figure = draw_figure3(results, args.figure or args.out / "figure3.png")
    summaries = [summary.model_dump(mode="json") for summary, _ in results]
    if args.json:
        payload = summaries[0] if len(summaries) == 1 else {"conditions": summaries,
                                                             "figure": str(figure)}
        print(json.dumps(payload, indent=2))
    else:
        for s in summaries:
            print(f"{s['condition']:>16}: N={s['trials']}, final mean distance "
                  f"{s['final_mean_distance']:.3f} [{s['final_ci'][0]:.3f}, {s['final_ci'][1]:.3f}]"
                  f", success {s['final_success_rate']:.2f}, {s['seconds_per_trial']:.2f} s/trial"
                  + (f", {s['hints_per_trial']:.1f} hints/trial" if s['hints_per_trial'] else ""))
        if figure is not None:
            print(f"Fig. 3 written to {figure}")
    sys.stdout.flush()
    return 0

"""``handover benchmark-pl``: the simulated preference-learning study of Sect. IV (and Fig. 3)."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

from app.learning.config import AcquisitionName

#: The six conditions of Sect. IV (qNEI q = 2, qNEI q = 5, EUBO; σ = 0 and 0.05) plus the Sobol
#: baseline. EUBO compares one new point with θ*, i.e. batches of q = 2.
PAPER_CONDITIONS: tuple[tuple[AcquisitionName, int, float], ...] = (
    *((acq, q, noise)
      for noise in (0.0, 0.05)
      for acq, q in ((AcquisitionName.QNEI, 2), (AcquisitionName.QNEI, 5),
                     (AcquisitionName.EUBO, 2))),
    (AcquisitionName.SOBOL, 5, 0.05),
)


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


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``benchmark-pl`` to the ``handover`` command."""
    parser = subparsers.add_parser(
        "benchmark-pl", help="simulated preference-learning study (paper Sect. IV, Fig. 3)",
        description=__doc__)
    parser.add_argument("--acq", choices=[a.value for a in AcquisitionName], default="qnei",
                        help="acquisition function (default: qnei, the paper's)")
    parser.add_argument("--q", type=_bounded(int, 2, 25), default=5,
                        help="interactions per batch, θ* included (default 5; EUBO: 2 is pairwise)")
    parser.add_argument("--noise", type=_bounded(float, 0.0, 1.0), default=0.0,
                        help="σ of y = u + j·N(0, σ²), eq. (16) (default 0)")
    parser.add_argument("--trials", type=_bounded(int, 1, 100_000), default=500,
                        help="trials per condition (default 500, the paper's)")
    parser.add_argument("--queries", type=_bounded(int, 2, 200), default=25,
                        help="unique points shown per trial, initial ones included (default 25)")
    parser.add_argument("--initial", type=_bounded(int, 1, 50), default=5,
                        help="initial Sobol points (default 5)")
    parser.add_argument("--seed", type=_bounded(int, 0, 2**62), default=0, help="study seed")
    parser.add_argument("--jobs", type=_bounded(int, 1, 64), default=1,
                        help="trials run in parallel processes, each single-threaded (default 1)")
    parser.add_argument("--out", type=Path, default=Path("out/benchmark-pl"),
                        help="output folder, one sub-folder per condition "
                        "(default out/benchmark-pl)")
    parser.add_argument("--paper", action="store_true",
                        help="run the six paper conditions plus sobol and draw Fig. 3")
    parser.add_argument("--figure", type=Path, default=None,
                        help="PNG path for Fig. 3 with --paper (default OUT/figure3.png)")
    parser.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the study as the arguments say; print a table (or JSON) of the final figures."""
    import torch

    from app.learning.simulation import StudyCondition
    from app.learning.study import run_condition

    torch.set_num_threads(1)  # trials are single-threaded; --jobs adds processes
    if args.initial > args.queries:
        raise ValueError(f"--initial = {args.initial} must not exceed --queries = {args.queries}")
    specs = PAPER_CONDITIONS if args.paper else ((AcquisitionName(args.acq), args.q, args.noise),)
    results = []
    for acq, q, noise in specs:
        condition = StudyCondition(acquisition=acq, q=q, noise=noise, n_unique=args.queries,
                                   n_initial=args.initial)
        results.append(run_condition(condition, trials=args.trials, seed=args.seed,
                                     jobs=args.jobs, out=args.out, progress=not args.no_progress))
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
                  f", success {s['final_success_rate']:.2f}, {s['seconds_per_trial']:.2f} s/trial")
        if figure is not None:
            print(f"Fig. 3 written to {figure}")
    sys.stdout.flush()
    return 0

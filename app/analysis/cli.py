"""``handover report``: the paper's tables, statistics and figures from a study folder."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from app.arguments import argument_type
from app.learning.config import GainRule, StoppingRule, epsilon_for


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``report`` and ``replay-stop`` to the ``handover`` command."""
    parser = subparsers.add_parser(
        "report", help="tables, statistics and figures of a study (paper Sect. VI)",
        description="Write a self-contained HTML report (Tables II-IV, the sign and Mann-Whitney "
                    "tests of Sect. VI, Fig. 4, learning curves; Fig. 3 with --benchmark), the "
                    "tables as CSV and the figures as PNG and SVG.")
    parser.add_argument("study", type=Path, help="study folder (one .sqlite per participant)")
    parser.add_argument("--out", type=Path, default=Path("out/report"),
                        help="output folder (default out/report)")
    parser.add_argument("--benchmark", type=Path, default=None,
                        help="a handover benchmark-pl output folder: adds Fig. 3")
    parser.add_argument("--xdf", type=Path, default=None, metavar="FILE",
                        help="an XDF recording of the study's LSL markers and the lab's own streams "
                             "(LabRecorder): each stream around each trial's Go (needs the 'xdf' extra)")
    parser.add_argument("--xdf-stream", action="append", default=[], metavar="NAME",
                        help="a stream of the --xdf file to draw (repeatable; default: every numeric "
                             "stream that is not the study's own)")
    parser.add_argument("--include-simulated", action="store_true",
                        help="count the simulated participant's answers too: the participants "
                             "whose learning used them (marked §) in Tables II-IV and the tests, "
                             "and its validation ratings and answers (by default only the "
                             "participants' own, and the experimenter's entries for them, count; "
                             "a study with no person's answer at all is reported whole)")
    parser.add_argument("--force", action="store_true",
                        help="report participants that handover doctor finds BAD too (they are "
                             "left out by default), with a warning for each")
    parser.set_defaults(func=run)
    register_replay(subparsers)


def register_replay(subparsers: argparse._SubParsersAction) -> None:
    """Add ``replay-stop`` to the ``handover`` command."""
    parser = subparsers.add_parser(
        "replay-stop", help="try a stopping rule on a study's stored sessions",
        description="Replay a stopping rule on the sessions of a study folder: per participant, "
                    "after which interaction it would have stopped learning, θ* then against the "
                    "session's final θ*, and the final learner's predicted preference between "
                    "them (docs/learning.md, 'Shorter sessions'). Several --chance (or "
                    "--threshold) values are replayed at once, so a lab can pick one from its "
                    "pilot.")
    parser.add_argument("study", type=Path, help="study folder (one .sqlite per participant)")
    parser.add_argument("--rule", choices=("gain", "settled"), default="gain",
                        help="gain: [protocol] stop_when_no_gain (default); settled: "
                             "stop_when_settled")
    parser.add_argument("--chance", type=_field(GainRule, "chance"), nargs="+", default=[0.2],
                        help="gain: stop when the next batch is at most this likely to find a "
                             "better handover, in (0, 1) (default 0.2)")
    parser.add_argument("--threshold", type=_field(StoppingRule, "threshold"), nargs="+",
                        default=[0.9],
                        help="settled: how sure, in [0.5, 1] (default 0.9)")
    parser.add_argument("--preference", type=_field(GainRule, "preference"), default=0.6,
                        help="better: preferred to θ* more than this share of the time (gain), "
                             "or the best preferred to θ* at most this often (settled), in "
                             "(0.5, 1) (default 0.6)")
    parser.add_argument("--min-batches", type=_field(GainRule, "min_batches"), default=1,
                        help="learning batches before any stop, 1-50 (default 1)")
    parser.add_argument("--out", type=Path, default=None,
                        help="also write the rows as CSV here (a file)")
    parser.set_defaults(func=run_replay)


def _field(model: type[BaseModel], name: str) -> Callable[[str], Any]:
    """An argparse type that validates a value as field ``name`` of ``model`` does (its range)."""

    def parse(text: str) -> Any:
        return getattr(model.model_validate({name: text}), name)

    parse.__name__ = name
    return argument_type(parse)


def run_replay(args: argparse.Namespace) -> int:
    import pandas as pd

    from app.analysis.stop_replay import replay_study

    rules: list[StoppingRule | GainRule] = (
        [GainRule(chance=c, preference=args.preference, min_batches=args.min_batches)
         for c in args.chance] if args.rule == "gain" else
        [StoppingRule(threshold=t, min_batches=args.min_batches,
                      epsilon=epsilon_for(args.preference)) for t in args.threshold])
    rows = replay_study(args.study, rules)
    if not rows:
        print(f"{args.study}: no participant has learner snapshots to replay", file=sys.stderr)
        return 1
    frame = pd.DataFrame([r.model_dump() for r in rows])
    for rule, group in frame.groupby("rule", sort=False):
        print(f"{rule}:")
        for row in group.itertuples():
            # the last recorded batch is never a stop: nothing after it would have been saved
            where = ("did not stop before the last recorded batch"
                     if row.signal is None or pd.isna(row.signal)
                     else f"signal {row.signal:.0%}")
            print(f"  {row.participant} ({row.scenario}): stops after {row.stopped_after} of "
                  f"{row.learned} ({where}); θ* then {_theta(row.theta_stop)}, final "
                  f"{_theta(row.theta_final)}; the final learner prefers its θ* "
                  f"{row.preferred_final:.0%} of the time")
        print(f"  median stop {group['stopped_after'].median():g} of "
              f"{group['learned'].median():g} interactions; mean preference for the final θ* "
              f"{group['preferred_final'].mean():.0%}")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        frame.to_csv(args.out, index=False)
        print(f"rows written to {args.out}")
    return 0


def _theta(theta: dict[str, float]) -> str:
    return "(" + ", ".join(f"{name} {value:.2f}" for name, value in theta.items()) + ")"


def run(args: argparse.Namespace) -> int:
    from app.analysis.report import build_report
    from app.analysis.report_page import unreadable_text
    from app.protocol.doctor import contradicted

    bad = contradicted(args.study) if args.study.is_dir() else {}
    for path, reason in bad.items() if args.force else ():
        print(f"warning: reported although {path.name}: {reason}", file=sys.stderr)
    report = build_report(args.study, args.out, args.benchmark,
                          include_simulated=args.include_simulated,
                          exclude=None if args.force else bad, xdf=args.xdf,
                          xdf_streams=args.xdf_stream)
    print(report.design.line)
    print(report.ratings_counted)
    for deviation in report.design.deviations:
        print(f"warning: study plan: {deviation}", file=sys.stderr)
    for code in report.counting.marked:
        print(f"warning: {code}: {report.counting.problem(code)}", file=sys.stderr)
    for line in report.answers_not_used:
        print(f"warning: {line}", file=sys.stderr)
    for name, reason in report.unreadable.items():
        print(f"warning: {unreadable_text(name, reason)}", file=sys.stderr)
    for why in report.recording_cut_short:
        print(f"warning: {args.xdf}: {why}", file=sys.stderr)
    if report.incomplete:
        print(f"warning: incomplete sessions, left out of the tests: {', '.join(report.incomplete)}",
              file=sys.stderr)
    for code, shown in report.not_blind.items():
        print(f"warning: {code}: validation {shown}", file=sys.stderr)
    for code, missing in report.gos_not_recorded.items():
        print(f"warning: {code}: trials {missing} have no go marker in the study's recordings",
              file=sys.stderr)
    for line in report.safety_over_limits:
        print(f"warning: past the lab's safety limits: {line}", file=sys.stderr)
    for test in report.tests:
        print(f"{test.name}: {test.summary()}")
    print(f"report: {report.html} ({len(report.tables)} tables, {len(report.figures)} figures)")
    return 0

"""``handover report``: the paper's tables, statistics and figures from a study folder."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``report`` to the ``handover`` command."""
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
    for test in report.tests:
        print(f"{test.name}: {test.summary()}")
    print(f"report: {report.html} ({len(report.tables)} tables, {len(report.figures)} figures)")
    return 0

"""``handover export`` (tidy tables) and ``handover doctor`` (a study folder checked); the headless
session, ``handover run-session``, is the session's (app/session/run_session.py)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from session_store.errors import StoreError
from session_store.paths import EXPORT_FORMATS


def register(subparsers: argparse._SubParsersAction) -> None:
    export = subparsers.add_parser(
        "export", help="export a study folder as tidy tables",
        description="Write one table per kind of row (trials, placements, comparisons, samples, "
                    "answers, ...) merging all participants, plus copies of the .sqlite files. "
                    "Nothing is written to the study folder (a read-only one is fine). A database "
                    "that cannot be read, or that holds another participant's session than its "
                    "name says (a copy), is left out and listed in left_out.csv; the others are "
                    "exported all the same.")
    export.add_argument("study", type=Path, help="study folder")
    export.add_argument("--format", choices=EXPORT_FORMATS, default="csv")
    export.add_argument("--out", type=Path, required=True, help="output folder")
    export.add_argument("--force", action="store_true",
                        help="export participants that handover doctor finds BAD too (they are "
                             "left out by default), with a warning for each")
    export.set_defaults(func=export_command)

    doctor = subparsers.add_parser(
        "doctor", help="check every participant database of a study folder",
        description="Check each .sqlite file of a study folder without changing it: SQLite's "
                    "integrity, the schema version, the event log replayed through the protocol "
                    "(an interaction completed twice, a placement for an unknown trial, ...), the "
                    "tables' consistency and who holds the writer's lock. Prints a verdict per "
                    "file; exits 1 if any file is bad.")
    doctor.add_argument("study", type=Path, help="study folder")
    doctor.set_defaults(func=doctor_command)


def export_command(args: argparse.Namespace) -> int:
    from app.protocol.doctor import contradicted
    from session_store.export import LEFT_OUT_FILE, export_study  # pandas: for this command only

    bad = contradicted(args.study) if Path(args.study).is_dir() else {}
    for path, reason in bad.items() if args.force else ():
        print(f"warning: exported although {path.name}: {reason}", file=sys.stderr)
    export = export_study(args.study, args.out, args.format, exclude=None if args.force else bad)
    for path, reason in export.left_out.items():
        print(f"warning: left out {path}: {reason}", file=sys.stderr)
    for table, (path, rows) in export.written.items():
        print(f"{table}: {rows} rows -> {path}")
    if export.left_out:
        print(f"{len(export.left_out)} database(s) left out, listed in "
              f"{Path(args.out) / LEFT_OUT_FILE}", file=sys.stderr)
    return 0


def doctor_command(args: argparse.Namespace) -> int:
    from app.protocol.doctor import examine_study

    if not args.study.is_dir():
        raise StoreError(f"study folder {args.study} does not exist")
    verdicts = examine_study(args.study)
    if not verdicts:
        raise StoreError(f"{args.study} holds no participant database (*.sqlite)")
    for verdict in verdicts:
        print(verdict.text())
    bad = [v.path.name for v in verdicts if not v.ok]
    print(f"{len(verdicts)} files: {len(verdicts) - len(bad)} OK, {len(bad)} bad"
          + (f" ({', '.join(bad)})" if bad else ""))
    return 1 if bad else 0

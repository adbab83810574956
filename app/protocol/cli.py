"""``handover run-session`` (a whole session headless) and ``handover export`` (tidy tables)."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from app.protocol.auto import run_auto
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from robot_io.cli import argument_type
from robot_io.config import load_config
from robot_io.simulated_hand import Scenario
from session_store.errors import StoreError
from session_store.export import FORMATS, export_study
from session_store.models import StudyConfig
from session_store.store import ParticipantStore, participant_path


def register(subparsers: argparse._SubParsersAction) -> None:
    run = subparsers.add_parser(
        "run-session", help="run a participant's whole session headless",
        description="Run the paper's protocol for one participant, headless, with the simulated "
                    "participant rating (--auto). --resume continues an interrupted session.")
    run.add_argument("--study", type=Path, required=True, help="study folder (one .sqlite per code)")
    run.add_argument("--participant", required=True, help="pseudonymous participant code")
    run.add_argument("--scenario", type=argument_type(Scenario.parse),
                     help="straightforward or perturbed (required for a new session)")
    run.add_argument("--auto", action="store_true",
                     help="the simulated participant rates and answers (required headless)")
    run.add_argument("--seed", type=int, default=0, help="seed of the session (new sessions)")
    run.add_argument("--resume", action="store_true",
                     help="continue an interrupted session (with --scenario: start it if it never "
                          "got created)")
    run.add_argument("--config", type=Path, help="controller TOML configuration (new sessions)")
    run.add_argument("--json", action="store_true", help="print a JSON summary at the end")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.set_defaults(func=run_session)

    export = subparsers.add_parser(
        "export", help="export a study folder as tidy tables",
        description="Write one table per kind of row (trials, placements, comparisons, samples, "
                    "answers, ...) merging all participants, plus copies of the .sqlite files.")
    export.add_argument("study", type=Path, help="study folder")
    export.add_argument("--format", choices=FORMATS, default="csv")
    export.add_argument("--out", type=Path, required=True, help="output folder")
    export.set_defaults(func=export_command)


def run_session(args: argparse.Namespace) -> int:
    if not args.auto:
        raise StoreError("a headless session needs --auto (the simulated participant); a session "
                         "with a person runs from the tablet and dashboard")
    exists = ParticipantStore.exists(args.study, args.participant)
    if args.resume and (exists or args.scenario is None):
        engine = SessionEngine.resume(args.study, args.participant)
        if args.scenario is not None and args.scenario != engine.config.scenario:
            raise StoreError(f"--scenario {args.scenario.value} differs from the session's "
                             f"{engine.config.scenario.value}")
    else:
        if exists:
            raise StoreError(f"participant {args.participant!r} already has a session in "
                             f"{args.study}: add --resume to continue it")
        if args.scenario is None:
            raise StoreError("--scenario is required for a new session")
        config = StudyConfig(scenario=args.scenario, seed=args.seed,
                             controller=load_config(args.config))
        engine = SessionEngine.create(args.study, args.participant, config)
    began = time.monotonic()
    try:
        run_auto(engine, SimulatedParticipant(engine.config.seed), progress=not args.no_progress)
        counts = engine.store.counts()
        snapshot = engine.store.rows("learner_snapshots")[-1]
    finally:
        engine.close()
    summary = {"participant": args.participant, "completed": engine.state.completed,
               "theta_star": {"a": snapshot.theta_star_a, "delta": snapshot.theta_star_delta,
                              "k": snapshot.theta_star_k},
               "seconds": round(time.monotonic() - began, 2),
               "database_bytes": participant_path(args.study, args.participant).stat().st_size,
               "counts": counts}
    if args.json:
        print(json.dumps(summary))
    else:
        star = summary["theta_star"]
        print(f"{args.participant}: {summary['completed']} handovers completed; θ* = (a "
              f"{star['a']:.2f}, δ {star['delta']:.2f}, k {star['k']:.2f}); "
              f"{summary['seconds']} s; database {summary['database_bytes'] / 1e6:.1f} MB")
    return 0


def export_command(args: argparse.Namespace) -> int:
    written = export_study(args.study, args.out, args.format)
    for table, (path, rows) in written.items():
        print(f"{table}: {rows} rows -> {path}")
    return 0

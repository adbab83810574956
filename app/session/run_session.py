"""``handover run-session``: a participant's whole session headless, with the simulated participant
rating and the simulated experimenter starting each trial, on the devices of the lab configuration."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from app.arguments import argument_type
from app.protocol.design import recorded_assignment
from app.protocol.learning_words import recorded_stop
from app.protocol.seeds import parse_seed
from app.protocol.state import Step
from app.protocol.stored_session import recorded_session
from app.session.cli import (
    Interrupted,
    add_rig_arguments,
    interruptible,
    open_runner,
    wait_until_done,
)
from app.session.config import load_lab_config
from robot_io.hands.simulated_hand import Scenario
from session_store.errors import StoreError
from session_store.read_only_copy import reading
from session_store.store import ParticipantStore, participant_path


def register(subparsers: argparse._SubParsersAction) -> None:
    run = subparsers.add_parser(
        "run-session", help="run a participant's whole session headless",
        description="Run the paper's protocol for one participant, headless, on the devices of the "
                    "lab configuration, with the simulated participant rating (--auto) and each trial "
                    "started automatically. With the mock arm and the simulated hand trials run on "
                    "simulated time unless --realtime. --resume continues an interrupted session.")
    run.add_argument("--study", type=Path, required=True, help="study folder (one .sqlite per code)")
    run.add_argument("--participant", required=True, help="pseudonymous participant code")
    run.add_argument("--scenario", type=argument_type(Scenario.parse), choices=list(Scenario),
                     help="straightforward or perturbed (required for a new session, unless the "
                          "--config has a [study] plan: then the plan's proposal; another choice "
                          "is recorded as a deviation)")
    run.add_argument("--auto", action="store_true",
                     help="the simulated participant rates and answers (required headless)")
    run.add_argument("--seed", type=argument_type(parse_seed), default=None,
                     help="seed of a new session, 0 … 2**63-1 (default: a fresh random one, "
                          "recorded); one another participant of the study has is refused unless "
                          "--reuse-seed")
    run.add_argument("--reuse-seed", action="store_true",
                     help="confirm a --seed that another participant of the study already has")
    run.add_argument("--resume", action="store_true",
                     help="continue an interrupted session (with --scenario: start it if it never "
                          "got created)")
    run.add_argument("--config", type=Path, help="the lab configuration file (TOML, docs/hardware.md)")
    add_rig_arguments(run)
    run.add_argument("--realtime", action="store_true",
                     help="run the mock arm and simulated hand on the wall clock, as on a rig")
    run.add_argument("--accept-rig-change", action="store_true",
                     help="continue a session recorded on a different rig (the change is recorded)")
    run.add_argument("--json", action="store_true", help="print a JSON summary at the end")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.set_defaults(func=run_session)


def run_session(args: argparse.Namespace) -> int:
    if not args.auto:
        raise StoreError("a headless session needs --auto (the simulated participant); a session "
                         "with a person runs from the tablet and dashboard")
    exists = ParticipantStore.exists(args.study, args.participant)
    resume = args.resume and (exists or args.scenario is None)
    if exists or resume:  # read only: a refusal below leaves the file as it is
        recorded = recorded_session(args.study, args.participant)
    if resume:
        if args.scenario is not None and args.scenario != recorded.config.scenario:
            raise StoreError(f"--scenario {args.scenario.value} differs from the session's "
                             f"{recorded.config.scenario.value}")
        if recorded.state.step is Step.DONE:
            raise StoreError(f"participant {args.participant!r}'s session is complete "
                             f"({recorded.state.completed} handovers): nothing to resume; "
                             "export or report it")
        if args.seed is not None and args.seed != recorded.config.seed:
            raise StoreError(f"--seed {args.seed} differs from the session's seed "
                             f"{recorded.config.seed}")
    elif exists:
        raise StoreError(f"participant {args.participant!r} already has a session in "
                         f"{args.study}: add --resume to continue it")
    lab = load_lab_config(args.config)
    if not (exists or resume) and args.scenario is None and lab.study is None:
        raise StoreError("--scenario is required for a new session (or a [study] plan in "
                         "--config, which proposes it)")
    simulated = lab.arm.simulated and lab.hand_source.simulated
    began = time.monotonic()
    try:
        with interruptible(), open_runner(
                args, lab, realtime=args.realtime or args.rehearse or not simulated,
                auto_experimenter=True) as runner:
            try:
                runner.set_auto(True)
                runner.open(args.participant, args.scenario, args.seed,
                            confirm_rig_change=args.accept_rig_change,
                            confirm_seed_reuse=args.reuse_seed)
                view = wait_until_done(runner, progress=not args.no_progress)
            except Interrupted as exc:
                runner.close(f"session closed by {exc.name}")
                raise
            observed = None if runner.rehearsal is None else runner.rehearsal.observed()
    except Interrupted as exc:
        print(f"{exc}; run-session --resume continues it", file=sys.stderr)
        return 128 + exc.signum
    if view.failed is not None:
        raise StoreError(f"the session stopped: {view.failed}")
    assert view.state is not None, "the view of an open session, done"
    with reading(args.study, args.participant) as store:  # read, never written: a plain file stays
        counts = store.counts()
        snapshot = store.rows("learner_snapshots")[-1]
        stopped = recorded_stop(store.events())
        assignment = recorded_assignment(store.participant().config)
    assert view.scenario is not None, "the view of an open session has its scenario"
    summary = {"participant": args.participant, "scenario": view.scenario.value,
               "study_plan": None if assignment is None else assignment.words(),
               "seed": view.seed, "completed": view.state.completed,
               "rig": view.arm, "hand": view.hand,
               "theta_star": {"a": snapshot.theta_star_a, "delta": snapshot.theta_star_delta,
                              "k": snapshot.theta_star_k},
               "learning": {"interactions": snapshot.after_interaction, "stopped_early": stopped},
               "seconds": round(time.monotonic() - began, 2),
               "database_bytes": participant_path(args.study, args.participant).stat().st_size,
               "counts": counts}
    if observed is not None:
        summary["rehearsal"] = observed
    if args.json:
        print(json.dumps(summary))
    else:
        star = summary["theta_star"]
        planned = "" if assignment is None else (
            f"; study plan: {assignment.words()}" + (
                "" if assignment.proposed is view.scenario else
                f" — DEVIATION: ran {view.scenario.value}"))
        print(f"{args.participant} ({view.scenario.value}, seed {view.seed}{planned}): "
              f"{summary['completed']} handovers completed on {view.arm}; "
              f"θ* = (a {star['a']:.2f}, δ {star['delta']:.2f}, k {star['k']:.2f}); "
              f"{summary['seconds']} s; database {summary['database_bytes'] / 1e6:.1f} MB")
        if stopped is not None:
            print(f"learning stopped early, after {snapshot.after_interaction} interactions: "
                  f"{stopped}")
        if observed is not None:
            print(f"the stand-in saw the gripper open {observed['gripper_opened']} times and "
                  f"{observed['moves_to_R']} moves to R; the TCP ended "
                  f"{1e3 * observed['tcp_to_R_m']:.1f} mm from R")
    return 0

"""``handover serve``: the participant's tablet and the experimenter's dashboard."""

from __future__ import annotations

import argparse
import logging
import signal
import threading
import tomllib
from pathlib import Path

from app.ui.server import HandoverServers, ServeOptions
from app.ui.session_runner import SessionRunner
from session_store.errors import StoreError

log = logging.getLogger(__name__)


def register(subparsers: argparse._SubParsersAction) -> None:
    serve = subparsers.add_parser(
        "serve", help="the tablet and the dashboard (web app) on the mock arm",
        description="Serve the participant's tablet and the experimenter's dashboard, two web "
                    "pages on two ports, with the mock arm, the simulated hand and the learner. "
                    "Ctrl-C stops the arm, then closes the session cleanly.")
    serve.add_argument("--study", type=Path, default=Path("study"),
                       help="study folder, one .sqlite per participant (default ./study)")
    serve.add_argument("--host", default="127.0.0.1",
                       help="address to bind (default 127.0.0.1; 0.0.0.0 for a tablet on the LAN)")
    serve.add_argument("--tablet-port", type=int, default=8080)
    serve.add_argument("--dashboard-port", type=int, default=8081)
    serve.add_argument("--token", help="dashboard access token (default: a random one, printed)")
    serve.add_argument("--rate", type=int, choices=(125, 500), default=500,
                       help="control rate of new sessions [Hz]")
    serve.add_argument("--protocol", type=Path,
                       help="TOML with protocol counts for new sessions (initial_trials, "
                            "batch_size, learning_batches, best_trials, validation_batches, "
                            "acquisition); the paper's by default")
    serve.add_argument("--realtime-priority", action="store_true",
                       help="run the control thread under SCHED_FIFO (needs root or CAP_SYS_NICE; "
                            "keeps 500 Hz cycles on time beside the browser and the learner)")
    serve.add_argument("--auto-participant", action="store_true",
                       help="the simulated participant rates and answers (demos, dry runs)")
    serve.set_defaults(func=serve_command)


def load_protocol(path: Path | None) -> dict:
    if path is None:
        return {}
    try:
        return tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise StoreError(f"protocol file {path}: {exc}") from exc


def serve_command(args: argparse.Namespace) -> int:
    runner = SessionRunner(args.study, rate_hz=args.rate, protocol=load_protocol(args.protocol),
                           realtime_priority=args.realtime_priority)
    servers = HandoverServers(runner, ServeOptions(host=args.host, tablet_port=args.tablet_port,
                                                   dashboard_port=args.dashboard_port,
                                                   token=args.token))
    if args.auto_participant:
        runner.set_auto(True)
    tablet, dashboard = servers.urls()
    print(f"tablet (participant):     {tablet}", flush=True)
    print(f"dashboard (experimenter): {dashboard}", flush=True)
    print(f"dashboard token:          {servers.token}", flush=True)
    quit_requested = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: quit_requested.set())
    quit_requested.wait()
    print("stopping the arm and closing the session ...", flush=True)
    servers.close()
    print("closed", flush=True)
    return 0

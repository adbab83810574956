"""``handover serve``: the participant's tablet and the experimenter's dashboard."""

from __future__ import annotations

import argparse
import ipaddress
import logging
import socket
from pathlib import Path
from typing import TYPE_CHECKING

from app.arguments import argument_type
from app.protocol.seeds import parse_seed
from app.session.cli import add_rig_arguments, open_runner
from app.session.config import load_lab_config
from app.session.signals import QuitSignal
from robot_io.hands.simulated_hand import Scenario
from session_store.paths import DEFAULT_STUDY

if TYPE_CHECKING:
    from app.session.runner import RunnerView

log = logging.getLogger(__name__)


def register(subparsers: argparse._SubParsersAction) -> None:
    serve = subparsers.add_parser(
        "serve", help="the tablet and the dashboard (web app) on the lab's rig",
        description="Serve the participant's tablet and the experimenter's dashboard, two web "
                    "pages on two ports, with the devices of the lab configuration (the mock arm and "
                    "the simulated hand by default, a UR5 and a tracker on a rig, or a rehearsal "
                    "rig with --rehearse) and the learner. Ctrl-C stops the arm, then closes the "
                    "session cleanly.")
    serve.add_argument("--study", type=Path, default=DEFAULT_STUDY,
                       help="study folder, one .sqlite per participant (default ./study)")
    serve.add_argument("--config", type=Path,
                       help="the lab configuration file (TOML, docs/hardware.md); the defaults "
                            "without it (mock arm, simulated hand, the paper's protocol)")
    serve.add_argument("--host", type=argument_type(host_address), default="127.0.0.1",
                       help="address to bind (default 127.0.0.1; 0.0.0.0 for a tablet on the LAN); "
                            "one this computer has")
    serve.add_argument("--tablet-port", type=argument_type(port_number), default=8080,
                       help="the tablet's port (default 8080; 0: any free port, the one bound is "
                            "printed)")
    serve.add_argument("--dashboard-port", type=argument_type(port_number), default=8081,
                       help="the dashboard's port (default 8081; 0: any free port, the one bound is "
                            "printed)")
    serve.add_argument("--token", help="dashboard access token (default: the study's own, created "
                                       "on first use and kept in <study>/.dashboard-token)")
    blinding = serve.add_mutually_exclusive_group()
    blinding.add_argument("--unblind", action="store_true",
                          help="show the θ and origin of validation trials on the dashboard (pilots "
                               "and debugging; recorded in the session)")
    blinding.add_argument("--blind", action="store_true",
                          help="the default: the dashboard hides the θ and origin of validation "
                               "trials, so the experimenter cannot tell which is θ* (recorded in "
                               "the session)")
    add_rig_arguments(serve)
    serve.add_argument("--auto-participant", action="store_true",
                       help="the simulated participant rates and answers (demos, dry runs)")
    serve.add_argument("--participant",
                       help="open this participant at start (resume it, or create it with "
                            "--scenario); refused at once while another process writes it")
    serve.add_argument("--scenario", type=argument_type(Scenario.parse), choices=list(Scenario),
                       help="with --participant: the scenario of a new participant")
    serve.add_argument("--seed", type=argument_type(parse_seed), default=None,
                       help="with --participant: the seed of a new participant (default: fresh)")
    serve.add_argument("--reuse-seed", action="store_true",
                       help="confirm a --seed that another participant of the study has")
    serve.set_defaults(func=serve_command)


def host_address(text: str) -> str:
    """An address of this computer to serve on: an IP address (or 0.0.0.0, every one) that a socket
    binds here. Refused at once otherwise; before, an address this computer does not have left
    ``serve`` hanging without a word. Host names are not resolved (a lookup can hang too)."""
    try:
        address = ipaddress.ip_address(text)
    except ValueError:
        raise ValueError(f"host = {text!r} is not an IP address (e.g. 127.0.0.1 for this computer "
                         "only, 0.0.0.0 for every network it is on)") from None
    family = socket.AF_INET6 if address.version == 6 else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((text, 0))
        except OSError as exc:
            raise ValueError(f"host = {text!r}: this computer cannot serve on that address "
                             f"({exc.strerror}); `ip address` lists the ones it has") from None
    return text


def port_number(text: str) -> int:
    """A TCP port to serve on: a whole number in 1–65535, or 0 for any free port (the system
    picks it when the server binds; serve prints the URLs with the ports bound). Port 0 lets two
    servers start side by side without guessing a free port first (a guess can be taken by
    another program before the server binds it)."""
    try:
        port = int(text)
    except ValueError:
        port = None
    if port is None or not 0 <= port <= 65535:
        raise ValueError(f"port = {text!r} must be a whole number in [1, 65535], or 0 for any "
                         "free port")
    return port


def participant_line(view: RunnerView) -> str:
    """The participant open at start, where their session stands, or how to open one."""
    if view.code is None or view.state is None:
        return "none open: create or open one on the dashboard"
    assert view.scenario is not None, "an open session's view has its scenario"
    return (f"{view.code} ({view.scenario.value}), {view.state.completed} of {view.interactions} "
            "handovers done")


def serve_command(args: argparse.Namespace) -> int:
    # here, not at the top: every handover command imports this module for its subcommand, and
    # viser costs each of them ~0.5 s of CPU
    import rich

    from app.ui.server import HandoverServers, ServeOptions

    lab = load_lab_config(args.config)
    if not args.verbose:
        rich.get_console().quiet = True  # viser's two boxed banners: the addresses are printed below
    with open_runner(args, lab, realtime=True) as runner:
        if args.auto_participant:
            runner.set_auto(True)
        if args.participant is not None:
            runner.open(args.participant, args.scenario, args.seed,
                        confirm_seed_reuse=args.reuse_seed)
        servers = HandoverServers(runner, ServeOptions(host=args.host, tablet_port=args.tablet_port,
                                                       dashboard_port=args.dashboard_port,
                                                       token=args.token, blind=not args.unblind))
        # from here on a Ctrl-C is never lost, and one during the close below does not cut it short
        with QuitSignal() as quit_signal:
            tablet, dashboard = servers.urls()
            print(f"tablet (participant):     {tablet}", flush=True)
            print(f"dashboard (experimenter): {dashboard}", flush=True)
            print(f"participant:              {participant_line(runner.view)}", flush=True)
            if args.unblind:
                print("validation:               NOT blind (--unblind): the dashboard shows which "
                      "trial is θ*", flush=True)
            print(f"dashboard token:          {servers.token}", flush=True)
            if runner.rehearsal is not None:
                print(f"rehearsal:                stand-in UR controller at {runner.rehearsal.host}",
                      flush=True)
            quit_signal.wait()
            print("stopping the arm and closing the session ...", flush=True)
            servers.close()
    print("closed", flush=True)
    return 0

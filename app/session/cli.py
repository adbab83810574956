"""What ``serve`` and ``run-session`` share on their command lines: the rehearsal rig and the
construction of the session runner (the composition root of both)."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator

from app.session.config import LabConfig
from app.session.rehearsal import Rehearsal
from app.session.runner import SessionRunner


def add_rig_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--rehearse", action="store_true",
                        help="rehearse without hardware on the real code path: a stand-in UR "
                             "controller on a loopback address and the simulated participant's hand "
                             "on LSL (see docs/hardware.md)")
    parser.add_argument("--rehearse-hand", choices=("lsl", "udp"), default="lsl",
                        help="with --rehearse: the tracker protocol of the simulated hand")
    parser.add_argument("--rehearse-series", choices=("cb3", "e"), default="cb3",
                        help="with --rehearse: a CB-series (125 Hz) or e-Series (500 Hz) stand-in")
    parser.add_argument("--realtime-priority", action="store_true",
                        help="run the rig's control loop under SCHED_FIFO (needs root or "
                             "CAP_SYS_NICE); also [loop] realtime_priority")


@contextlib.contextmanager
def open_runner(args: argparse.Namespace, lab: LabConfig, *, realtime: bool,
                auto_experimenter: bool = False) -> Iterator[SessionRunner]:
    """The session runner on the lab's devices, or on a rehearsal rig; closed (arm stopped first)
    on the way out, also on Ctrl-C."""
    priority = args.realtime_priority or lab.loop.realtime_priority
    rehearsal = (Rehearsal(lab, hand=args.rehearse_hand, series=args.rehearse_series)
                 if args.rehearse else None)
    runner = SessionRunner(args.study, lab, realtime=realtime, rehearsal=rehearsal,
                           realtime_priority=priority, auto_experimenter=auto_experimenter)
    try:
        yield runner
    finally:
        runner.close()

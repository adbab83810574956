"""What ``serve`` and ``run-session`` share on their command lines: the rehearsal rig and the
construction of the session runner (the composition root of both); and, for ``run-session``, the
wait for a headless session to finish."""

from __future__ import annotations

import argparse
import contextlib
import logging
import signal
import sys
import threading
from collections.abc import Iterator
from typing import cast, get_args

from tqdm import tqdm

from app.protocol.state import Step
from app.session.config import LabConfig
from app.session.rehearsal import HandKind, Rehearsal
from app.session.runner import RunnerView, SessionRunner
from app.session.signals import uninterrupted
from robot_io.clock import resolve_priority
from robot_io.errors import ConfigError

log = logging.getLogger(__name__)
#: The signals that end a session's command as Ctrl-C does.
SIGNALS = (signal.SIGINT, signal.SIGTERM)


def add_rig_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--rehearse", action="store_true",
                        help="rehearse without hardware on the real code path: a stand-in UR "
                             "controller on a loopback address and the simulated participant's hand "
                             "on LSL (see docs/hardware.md)")
    parser.add_argument("--rehearse-hand", choices=("lsl", "udp", "natnet"),
                        help="with --rehearse: the tracker protocol of the simulated hand (default: "
                             "[hand_source] kind when it is one of these, else lsl)")
    parser.add_argument("--rehearse-series", choices=("cb3", "e"), default="cb3",
                        help="with --rehearse: a CB-series (125 Hz) or e-Series (500 Hz) stand-in")
    parser.add_argument("--realtime-priority", action=argparse.BooleanOptionalAction, default=None,
                        help="the rig under SCHED_FIFO: --realtime-priority refuses to start "
                             "without it, --no-realtime-priority never asks for it (default: "
                             "[loop] realtime_priority, \"auto\": where the OS permits it, saying "
                             "so at start where it does not; docs/hardware.md)")


def rehearsed_hand(args: argparse.Namespace, lab: LabConfig) -> HandKind:
    """The tracker protocol a rehearsal plays the hand on: ``--rehearse-hand``, else the lab's own
    ``[hand_source] kind`` when it is a tracker's (a lab on NatNet rehearses NatNet), else LSL (a
    simulated hand has no tracker to rehearse). A lab on Vicon is refused without ``--rehearse-hand``:
    no stand-in speaks Vicon's DataStream (docs/hardware.md, "Vicon"), and a rehearsal that swapped
    the tracker unasked would let the lab believe its Vicon link had been rehearsed."""
    if args.rehearse_hand is not None:
        return args.rehearse_hand
    kind = lab.hand_source.kind
    if kind == "vicon":
        raise ConfigError('--rehearse cannot play the hand on Vicon\'s DataStream ([hand_source] kind = '
                          '"vicon"): there is no stand-in Vicon server. Say which protocol stands in '
                          "for it, e.g. --rehearse-hand lsl (the rest of the session runs as on the "
                          "rig; the Vicon link is checked by `handover check-devices` on the rig)")
    return cast(HandKind, kind) if kind in get_args(HandKind) else "lsl"


class Interrupted(Exception):
    """A signal that ends a command as Ctrl-C does: the arm stopped, the session closed."""

    def __init__(self, signum: int) -> None:
        self.signum, self.name = signum, signal.Signals(signum).name
        super().__init__(f"{self.name}: the arm is stopped and the session is closed")


@contextlib.contextmanager
def interruptible() -> Iterator[None]:
    """Inside, SIGINT (Ctrl-C) and SIGTERM (a process manager, ``kill``) raise :class:`Interrupted`
    in the main thread, once: a second signal while the session closes is ignored, so the close
    that records the running trial and stops the arm is not itself cut short (the rig's backstop
    stops the arm if this process dies)."""
    def interrupt(signum: int, _frame: object) -> None:
        for ignored in SIGNALS:
            signal.signal(ignored, signal.SIG_IGN)
        raise Interrupted(signum)

    before = {signum: signal.signal(signum, interrupt) for signum in SIGNALS}
    try:
        yield
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)


def rig_priority(args: argparse.Namespace, lab: LabConfig, *, realtime: bool) -> bool:
    """Whether the rig runs under SCHED_FIFO: ``--[no-]realtime-priority``, else ``[loop]
    realtime_priority``, resolved here at start (robot_io.clock.resolve_priority): refused at once
    when it is required and the OS will not grant it, and said on stderr when "auto" runs without.
    Never on simulated time: a rig that computes trials as fast as it can must not hold a core."""
    setting = lab.loop.realtime_priority if args.realtime_priority is None else args.realtime_priority
    if not realtime:
        return False
    wanted, note = resolve_priority(setting)
    if note is not None:
        log.warning("%s", note)
    return wanted


@contextlib.contextmanager
def open_runner(args: argparse.Namespace, lab: LabConfig, *, realtime: bool,
                auto_experimenter: bool = False) -> Iterator[SessionRunner]:
    """The session runner on the lab's devices, or on a rehearsal rig; closed (arm stopped first)
    on the way out, also on Ctrl-C."""
    priority = rig_priority(args, lab, realtime=realtime)
    rehearsal = (Rehearsal(lab, hand=rehearsed_hand(args, lab), series=args.rehearse_series)
                 if args.rehearse else None)
    try:
        runner = SessionRunner(args.study, lab, realtime=realtime, rehearsal=rehearsal,
                               realtime_priority=priority, auto_experimenter=auto_experimenter)
    except BaseException:  # a signal or a failure before the runner owns the rehearsal
        if rehearsal is not None:
            rehearsal.close()
        raise
    try:
        yield runner
    finally:
        with uninterrupted("closing the session"):
            runner.close()


def wait_until_done(runner: SessionRunner, progress: bool) -> RunnerView:
    """Block until the session is done or the simulated experimenter gave up; a progress bar."""
    done = threading.Event()
    with tqdm(total=None, unit="handover", disable=not progress, file=sys.stderr) as bar:
        def listen(view: RunnerView) -> None:
            if view.state is not None:
                bar.total = view.interactions
                bar.n = view.state.completed
                bar.refresh()
            if view.step is Step.DONE or view.failed is not None:
                done.set()

        runner.subscribe(listen)
        listen(runner.view)
        done.wait()
    return runner.view

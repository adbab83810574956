"""The ``handover`` console command: its description and options; each package registers its own
subcommands here (:data:`_COMMAND_MODULES`)."""

from __future__ import annotations

import argparse
import logging
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from pydantic import ValidationError

from app.protocol.errors import ProtocolError
from robot_io.errors import RobotIOError, explain
from robot_io.lsl_log import quiet_liblsl
from session_store import lock as writer_lock
from session_store.errors import StoreError
from session_store.paths import DEFAULT_STUDY, participant_path, unreadable_study

#: Modules that contribute subcommands: each has ``register(subparsers) -> None`` and sets
#: ``func(args) -> int`` on its parsers.
_COMMAND_MODULES: tuple[str, ...] = (
    "app.session.rig_cli",
    "app.learning.cli",
    "app.session.run_session",
    "app.protocol.cli",
    "app.analysis.cli",
    "app.ui.cli",
)


#: Commands that write a participant's database (``--participant``).
WRITERS = ("run-session", "serve")


def reserve_participant(argv: Sequence[str]) -> writer_lock.WriterLock | None:
    """For a command that writes an existing participant, take its writer lock first — before
    the command's slow imports (torch, BoTorch, viser) — so that a second writer is refused at once,
    naming the holder. The lock is kept for the command (its session claims it). Anything odd in
    the arguments, the lab configuration included, is left to the full command, which reports it
    before anything is written (the lock file included)."""
    command = next((word for word in argv if not word.startswith("-")), None)
    if command not in WRITERS:
        return None
    early = argparse.ArgumentParser(add_help=False)
    early.add_argument("--study", type=Path, default=DEFAULT_STUDY)
    early.add_argument("--participant")
    early.add_argument("--config", type=Path)
    known, _ = early.parse_known_args(argv)
    if known.participant is None:
        return None
    try:
        database = participant_path(known.study, known.participant)
    except StoreError:
        return None
    try:
        exists = database.exists()
    except PermissionError as exc:  # another user's study folder (mode 700)
        raise unreadable_study(known.study, exc) from None
    if not exists:
        return None  # a new participant: its creation takes the lock, after the arguments are valid
    from app.session.config import load_lab_config

    try:
        load_lab_config(known.config)
    except (ValidationError, RobotIOError):
        return None
    return writer_lock.reserve(database, argv=["handover", *argv])


#: What ``handover --help`` opens with, and the commands a lab starts with (plain text, printed as
#: it is written).
DESCRIPTION = """\
handover-lab: adaptive robot-to-human handovers for human-robot interaction
studies. A robot arm hands an object to a participant; the participant rates
each handover on a tablet, and preference learning picks the next one. Each
participant's session is stored in a study folder."""
EPILOG = """\
to start:
  handover serve --study ./study
      the tablet and the dashboard: open the two addresses it prints
  handover check-devices --config lab.toml
      connect to the lab's arm, tracker and gripper; move nothing
  handover report ./study --out ./report
      the paper's tables, tests and figures of a study

'handover COMMAND --help' describes each command."""


def version() -> str:
    """The installed package's version."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    try:
        return installed("handover-lab")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


def build_parser() -> argparse.ArgumentParser:
    import importlib

    parser = argparse.ArgumentParser(prog="handover", description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log at INFO level")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in _COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return parser


def tolerate_any_encoding() -> None:
    """Output never fails a command that did its work: on a terminal or pipe whose encoding lacks a
    character (``LANG=C``, ``PYTHONIOENCODING=ascii``: no θ, δ, τ), it is written as an escape
    (``\\u03b8``) instead of raising UnicodeEncodeError after the session was stored."""
    for stream in (sys.stdout, sys.stderr):
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    tolerate_any_encoding()
    command = next((word for word in argv if not word.startswith("-")), "")
    try:
        return _run(argv, command)
    except KeyboardInterrupt:  # Ctrl-C before a session's own handler was in place: a sentence
        print(f"handover {command}: interrupted (Ctrl-C)", file=sys.stderr)
        return 128 + signal.SIGINT


def _run(argv: list[str], command: str) -> int:
    try:
        reserve_participant(argv)
    except StoreError as exc:
        print(f"handover {command}: error: {exc}", file=sys.stderr)
        return 2
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if not args.verbose:
        quiet_liblsl()
    func: Callable[[argparse.Namespace], int] = args.func
    try:
        return func(args)
    except (ValidationError, RobotIOError, StoreError, ProtocolError, ValueError) as exc:
        print(f"handover {args.command}: error: {explain(exc)}", file=sys.stderr)
        return 2
    except OSError as exc:  # a full disk, a missing or read-only folder, a port: the system's words
        logging.getLogger(__name__).info("%s failed", args.command, exc_info=True)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"handover {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

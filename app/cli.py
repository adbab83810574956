"""The ``handover`` console command. Each package registers its own subcommands here."""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable, Sequence

from pydantic import ValidationError

from robot_io.errors import RobotIOError, explain
from session_store.errors import StoreError

#: Modules that contribute subcommands: each has ``register(subparsers) -> None`` and sets
#: ``func(args) -> int`` on its parsers.
_COMMAND_MODULES: tuple[str, ...] = (
    "robot_io.cli",
    "app.learning.cli",
    "app.protocol.cli",
    "app.analysis.cli",
    "app.ui.cli",
)


def build_parser() -> argparse.ArgumentParser:
    import importlib

    parser = argparse.ArgumentParser(prog="handover", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="log at INFO level")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in _COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    func: Callable[[argparse.Namespace], int] = args.func
    try:
        return func(args)
    except (ValidationError, RobotIOError, StoreError, ValueError) as exc:
        print(f"handover {args.command}: error: {explain(exc)}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

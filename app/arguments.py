"""Argument types of the ``handover`` commands: a parser whose refusal argparse shows in the
project's words (field, value, allowed range)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TypeVar

from robot_io.errors import explain

T = TypeVar("T")


def argument_type(parse: Callable[[str], T]) -> Callable[[str], T]:
    """Wrap a parser so that argparse shows its message (field, value, allowed range)."""

    def wrapped(text: str) -> T:
        try:
            return parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(explain(exc)) from exc

    wrapped.__name__ = parse.__name__
    return wrapped

"""The exception hierarchy of ``robot_io``: every message names the field, the value and the range."""

from __future__ import annotations


class RobotIOError(Exception):
    """Base of every error raised by ``robot_io``."""


class ConfigError(RobotIOError, ValueError):
    """A parameter or configuration value outside its allowed range."""


class HandSourceError(RobotIOError):
    """The hand source delivered no, stale or invalid samples."""


class ArmFault(RobotIOError):
    """The arm refused a command or is in a fault state (stopped, protective stop, limits)."""


def explain(exc: Exception) -> str:
    """One line for a user: a pydantic ValidationError becomes its messages without the preamble."""
    errors = getattr(exc, "errors", None)
    if callable(errors):
        return "; ".join(str(e.get("msg", e)).removeprefix("Value error, ") for e in errors())
    return str(exc)

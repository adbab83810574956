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


class GripperFault(RobotIOError):
    """The gripper does not answer, reports a fault code, or lost the object it held."""


class MoveStopped(RobotIOError):
    """A bounded move (to the start pose R) was stopped on request before it arrived."""


def explain(exc: Exception) -> str:
    """One line for a user. A pydantic ValidationError becomes ``field = value: message`` per error
    (our own validators already say the field and value, and are kept as they are)."""
    errors = getattr(exc, "errors", None)
    if not callable(errors):
        return str(exc)
    parts = []
    for error in errors():
        message = str(error.get("msg", "")).removeprefix("Value error, ")
        loc = error.get("loc", ())
        field = ".".join(str(part) for part in loc)
        name = next((str(part) for part in reversed(loc) if not isinstance(part, int)), "")
        if field and name not in message:
            message = f"{field} = {error.get('input')!r}: {message}"
        parts.append(message)
    return "; ".join(parts)

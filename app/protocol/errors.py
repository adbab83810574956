"""The exception hierarchy of the protocol: refused actions and event logs that break its rules."""

from __future__ import annotations


class ProtocolError(Exception):
    """Base of every error raised by ``app.protocol``."""


class RefusedAction(ProtocolError, ValueError):
    """An action that the protocol's current state does not allow (nothing was written)."""


class EventLogError(ProtocolError):
    """A stored event log that breaks the protocol: an event that does not parse, or one that the
    state it is applied to does not allow (an interaction completed twice, a placement for a trial
    that is not waiting for one). Names the event's number and what is wrong."""

    def __init__(self, seq: int | None, kind: str, problem: str) -> None:
        self.seq, self.kind, self.problem = seq, kind, problem
        super().__init__(f"event {seq if seq is not None else '(new)'} ({kind}): {problem}")

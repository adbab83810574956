"""A stored session read back: its plan, its event log and the state the protocol replays from it."""

from __future__ import annotations

from typing import NamedTuple

from app.protocol.plan import protocol_slots
from app.protocol.state import SessionState, replay
from app.protocol.study import StudyConfig
from session_store.models import Event
from session_store.store import ParticipantStore


class StoredSession(NamedTuple):
    config: StudyConfig
    events: list[Event]
    state: SessionState


def stored_session(store: ParticipantStore) -> StoredSession:
    """The session in ``store`` (any store: one open for writing or an in-memory copy from
    :func:`session_store.reading.reading`), replayed through the protocol."""
    config = StudyConfig.model_validate(store.participant().config)
    events = store.events()
    return StoredSession(config, events, replay(protocol_slots(config), events))

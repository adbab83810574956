"""A participant's session read back from its database without writing anything: its plan, its
event log and the state the protocol replays from it (:func:`stored_session`, from any open store),
and, read from the study folder, the rig it last ran on (:func:`recorded_session`: ``run-session``
checks its flags against it; opening a participant compares its rig with the lab's before anything is
written)."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

from app.protocol.plan import protocol_slots
from app.protocol.rig import rig_of
from app.protocol.state import SessionState, replay
from app.protocol.study_config import StudyConfig
from session_store.models import Event
from session_store.read_only_copy import reading
from session_store.store import ParticipantStore


class StoredSession(NamedTuple):
    config: StudyConfig
    events: list[Event]
    state: SessionState


def stored_session(store: ParticipantStore) -> StoredSession:
    """The session in ``store`` (any store: one open for writing or an in-memory copy from
    :func:`session_store.read_only_copy.reading`), replayed through the protocol."""
    config = StudyConfig.model_validate(store.participant().config)
    events = store.events()
    return StoredSession(config, events, replay(protocol_slots(config), events))


class RecordedSession(NamedTuple):
    """A stored session as it stands: its plan, the rig it last ran on, and its state."""

    config: StudyConfig
    rig: dict
    state: SessionState


def recorded_session(study: Path, code: str) -> RecordedSession:
    """A stored session, read without writing anything (from a copy in memory: the file is neither
    migrated nor touched)."""
    with reading(study, code) as store:
        config, events, state = stored_session(store)
    rig = rig_of(config.controller.model_dump(mode="json"))
    for event in reversed(events):
        if event.kind == "devices_recorded":
            rig = rig_of(event.payload.get("rig") or event.payload["config"])
            break
    return RecordedSession(config, rig, state)


def describe_change(before: dict, after: dict) -> str:
    """The rig tables that differ, in words: ``arm.kind 'mock' → 'ur'; ur.host …``."""
    changes = []
    for table in before:
        old, new = before[table] or {}, after[table] or {}
        for key in sorted(set(old) | set(new)):
            if old.get(key) != new.get(key):
                changes.append(f"{table}.{key} {old.get(key)!r} → {new.get(key)!r}")
    return "; ".join(changes) or "no difference"

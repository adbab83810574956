"""The study at a glance: every participant of the study folder, from their databases alone.

Each participant's protocol state is rebuilt from its event log (:func:`app.protocol.state.replay`),
so the overview says what a resumed session would continue with: how many handovers are completed,
whether the session is complete, ended early (paused by the experimenter), open in this server now,
or was interrupted (the server stopped while it was open), and when anything last happened.
"""

from __future__ import annotations

import logging
from enum import StrEnum
from pathlib import Path

from pydantic import BaseModel, ConfigDict

from app.protocol.design import Assignment
from app.protocol.state import Step
from app.protocol.stored_session import stored_session
from robot_io.hands.simulated_hand import Scenario
from session_store.errors import StoreError
from session_store.read_only_copy import reading
from session_store.store import ParticipantStore, participant_codes, participant_path

log = logging.getLogger(__name__)


class SessionStatus(StrEnum):
    OPEN = "open now"
    COMPLETE = "complete"
    PAUSED = "paused"  # ended or paused by the experimenter before it was complete
    INTERRUPTED = "interrupted"  # not complete and not paused: the server stopped while it ran
    UNREADABLE = "unreadable"


class ParticipantSummary(BaseModel):
    model_config = ConfigDict(frozen=True)

    code: str
    scenario: Scenario | None = None
    completed: int = 0  # handovers completed
    interactions: int = 0  # handovers in the plan as it stands (an early stop skips some)
    status: SessionStatus
    last_activity: str | None = None  # UTC ISO-8601 time of the last event
    detail: str = ""  # why it is unreadable, or the pause's reason
    assignment: Assignment | None = None  # what the study plan proposed for it ([study])


def summarise(study: Path, code: str, open_code: str | None = None) -> ParticipantSummary:
    """One participant's line of the overview (read only: nothing is written)."""
    try:
        with reading(study, code) as store:
            return summary_of(store, code, open_code)
    except StoreError as exc:  # the file could not be read
        return ParticipantSummary(code=code, status=SessionStatus.UNREADABLE, detail=str(exc))


def summary_of(store: ParticipantStore, code: str, open_code: str | None = None) -> ParticipantSummary:
    """The line of the participant in ``store`` (a copy in memory, or the open session's own)."""
    try:
        config, events, state = stored_session(store)
    except StoreError as exc:
        return ParticipantSummary(code=code, status=SessionStatus.UNREADABLE, detail=str(exc))
    paused = [e for e in events if e.kind == "paused"]
    status = (SessionStatus.OPEN if code == open_code else
              SessionStatus.COMPLETE if state.step is Step.DONE else
              SessionStatus.PAUSED if state.paused else SessionStatus.INTERRUPTED)
    return ParticipantSummary(
        code=code, scenario=config.scenario, completed=state.completed,
        interactions=state.interactions, status=status, assignment=config.assignment,
        last_activity=events[-1].at if events else None,
        detail=paused[-1].payload.get("reason", "") if state.paused and paused else "")


def _signature(path: Path) -> tuple[tuple[int, int, int, int] | None, ...]:
    """What a write to a participant's database changes: the inode, size and times of its file and
    of its WAL (a writer commits into the WAL; a checkpoint rewrites the file)."""
    signature: list[tuple[int, int, int, int] | None] = []
    for file in (path, path.with_name(path.name + "-wal")):
        try:
            stat = file.stat()
        except FileNotFoundError:
            signature.append(None)
            continue
        signature.append((stat.st_ino, stat.st_size, stat.st_mtime_ns, stat.st_ctime_ns))
    return tuple(signature)


class StudyOverview:
    """Every participant of a study folder, sorted by code, kept between refreshes.

    The dashboard refreshes the overview after every trial. Reading a line copies the participant's
    database into memory and replays its events (~0.1 CPU-s at 25 MB), so a line is read again only
    when its database changed on disk (:func:`_signature`: another process wrote it), and the open
    session's line comes from the store that session writes, without a copy.
    """

    def __init__(self, study: Path) -> None:
        self.study = Path(study)
        self._lines: dict[str, tuple[tuple, ParticipantSummary]] = {}

    def lines(self, open_store: ParticipantStore | None = None,
              open_code: str | None = None) -> list[ParticipantSummary]:
        if not self.study.exists():
            return []
        lines = []
        for code in participant_codes(self.study):
            if open_store is not None and code == open_code:
                lines.append(summary_of(open_store, code, open_code))
                continue
            signature = _signature(participant_path(self.study, code))
            known = self._lines.get(code)
            if known is None or known[0] != signature:  # the signature before the read: a write
                known = (signature, summarise(self.study, code))  # during it is read next time
                self._lines[code] = known
            lines.append(known[1])
        return lines

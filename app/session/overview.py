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

from app.protocol.state import Step
from app.protocol.stored import stored_session
from robot_io.simulated_hand import Scenario
from session_store.errors import StoreError
from session_store.reading import reading
from session_store.store import participant_codes

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
    interactions: int = 0  # handovers in the plan
    status: SessionStatus
    last_activity: str | None = None  # UTC ISO-8601 time of the last event
    detail: str = ""  # why it is unreadable, or the pause's reason


def summarise(study: Path, code: str, open_code: str | None = None) -> ParticipantSummary:
    """One participant's line of the overview (read only: nothing is written)."""
    try:
        with reading(study, code) as store:
            config, events, state = stored_session(store)
    except StoreError as exc:
        return ParticipantSummary(code=code, status=SessionStatus.UNREADABLE, detail=str(exc))
    paused = [e for e in events if e.kind == "paused"]
    status = (SessionStatus.OPEN if code == open_code else
              SessionStatus.COMPLETE if state.step is Step.DONE else
              SessionStatus.PAUSED if state.paused else SessionStatus.INTERRUPTED)
    return ParticipantSummary(
        code=code, scenario=config.scenario, completed=state.completed,
        interactions=config.interactions, status=status,
        last_activity=events[-1].at if events else None,
        detail=paused[-1].payload.get("reason", "") if state.paused and paused else "")


def study_overview(study: Path, open_code: str | None = None) -> list[ParticipantSummary]:
    """Every participant of ``study``, sorted by code."""
    if not Path(study).exists():
        return []
    return [summarise(study, code, open_code) for code in participant_codes(study)]

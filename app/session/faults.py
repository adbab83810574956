"""Faults a rehearsal can stage on purpose, so the lab engineer sees how the rig reacts before a
participant ever does: the tracker losing the hand, a protective stop, a participant who does not
take the object, the rig process dying. Each acts on the rehearsal's own stand-ins (the hand
publisher, the stand-in controller) or on the rig process, exactly as the real fault would reach the
application; what follows (abort, ``not_taken``, the arm's fault) is the rig's ordinary handling,
recorded as usual. Only a rehearsal has them: on the rig they are refused."""

from __future__ import annotations

import os
import signal
from enum import StrEnum

from app.protocol.errors import RefusedAction
from app.session.rehearsal import Rehearsal
from robot_io.rig.client import RigClient

#: how long a staged tracker loss hides the marker (s): longer than the rig's tracker timeout
TRACKER_LOSS_S = 1.5


class StagedFault(StrEnum):
    """A fault a rehearsal stages; its value is the button's words on the dashboard."""

    TRACKER_LOST = f"Hide the hand from the tracker for {TRACKER_LOSS_S:g} s"
    PROTECTIVE_STOP = "Protective stop on the controller"
    RIG_KILLED = "Kill the rig process"


def stage(fault: StagedFault, rehearsal: Rehearsal | None, rig: RigClient | None) -> str:
    """Stage ``fault`` now; the message for the session's log. Refused outside a rehearsal, and
    a rig kill when no rig process runs."""
    if rehearsal is None:
        raise RefusedAction(f"{fault.value!r} refused: faults are staged only in a rehearsal")
    if fault is StagedFault.TRACKER_LOST:
        rehearsal.hand_publisher().occlude(TRACKER_LOSS_S)
    elif fault is StagedFault.PROTECTIVE_STOP:
        rehearsal.control("protective_stop")
    else:
        pid = None if rig is None else rig.pid  # read once: None once the rig's handle is released
        if pid is None:
            raise RefusedAction(f"{fault.value!r} refused: no rig process is running")
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError as exc:
            raise RefusedAction(f"{fault.value!r} refused: the rig process has already ended") from exc
    return f"rehearsal: staged fault — {fault.value}"


def refuse_object(rehearsal: Rehearsal | None, refuse: bool) -> str:
    """The simulated participant stops (or starts again) taking the object at H: no pull, so the
    hold times out and the trial ends ``not_taken``."""
    if rehearsal is None:
        raise RefusedAction("refused: the participant's behaviour is staged only in a rehearsal")
    rehearsal.configure_pull(taken=not refuse)
    return ("rehearsal: the simulated participant will not take the object" if refuse else
            "rehearsal: the simulated participant takes the object again")

"""Opening a participant's session: resumed if it has one, else created — under the participant's
writer lock, with the seed checked against the study folder, and refused on a rig other than the one
it was recorded on unless the change is confirmed (then the change is recorded). Runs on the session
runner's engine thread."""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

from app.protocol.design import PlanStatus, plan_participants
from app.protocol.engine import SessionEngine
from app.protocol.errors import RefusedAction
from app.protocol.rig import RIG_TABLES, rig_of
from app.protocol.seeds import choose_seed
from app.protocol.stored_session import describe_change, recorded_session
from app.protocol.study_config import StudyConfig
from app.session.config import LabConfig
from app.session.rehearsal import rehearsal_rig
from robot_io.config import ControllerConfig
from robot_io.hands.simulated_hand import Scenario
from robot_io.rig.messages import DeviceReport
from session_store import lock as writer_lock
from session_store.catalog import stored_configs
from session_store.paths import refuse_case_twin
from session_store.store import ParticipantStore, participant_path


class Opened(NamedTuple):
    """A session open for writing: its engine, the writer lock it holds, the devices its rig
    opened, and the rig it was recorded on when that differs from this one (None: the same rig, or
    a new session)."""

    engine: SessionEngine
    lock: writer_lock.WriterLock
    devices: DeviceReport
    changed_from: dict | None


def rig_identity(lab: LabConfig, rehearsal: bool) -> dict:
    """The rig tables a resume compares (a rehearsal's per-run addresses left out)."""
    rig = rig_of(lab.model_dump(mode="json"))
    return rehearsal_rig(rig) if rehearsal else rig


def trial_config(lab: LabConfig, session: StudyConfig) -> ControllerConfig:
    """The session's controller configuration on this lab's rig."""
    rig = {table: getattr(lab, table) for table in RIG_TABLES}
    return session.controller.model_copy(update=rig)


def open_session(study: Path, lab: LabConfig, identity: dict, code: str, scenario: Scenario | None,
                 seed: int | None, *, confirm_rig_change: bool, confirm_seed_reuse: bool,
                 open_rig: Callable[[StudyConfig], DeviceReport]) -> Opened:
    """Resume ``code``'s session, or create it (with ``scenario``; None: the one the study plan
    proposes) if it has none, with the plan's proposal recorded (``[study]``: app.protocol.design);
    refused at once while another writer holds the participant. A new session gets ``seed`` (a
    fresh random one when None; one another participant has only with ``confirm_seed_reuse``).
    ``open_rig`` opens
    the rig for the session's plan before the engine (its devices); a session recorded on a rig other than
    ``identity`` is refused unless ``confirm_rig_change``."""
    exists = ParticipantStore.exists(study, code)
    if not exists:
        refuse_case_twin(study, code)
    if not exists and scenario is None and lab.study is None:
        raise RefusedAction(f"participant {code!r} has no session yet: choose a scenario "
                            "to create one")
    with contextlib.ExitStack() as creation:
        if exists:
            config, recorded, _ = recorded_session(study, code)
            changed = recorded if recorded != identity else None
            if changed is not None and not confirm_rig_change:
                raise RefusedAction(
                    f"participant {code!r} was recorded on a different rig "
                    f"({describe_change(recorded, identity)}); to continue on this "
                    "one, confirm the rig change (dashboard: 'Confirm a rig change'; "
                    "run-session: --accept-rig-change)")
        else:
            # the session plan is validated before anything is written (with the scenario and
            # seed asked for, or stand-ins); the seed and the study plan's next proposal are read,
            # and the session created, in one step for the study folder
            stand_in = scenario or (None if lab.study is None else lab.study.scenarios[0])
            assert stand_in is not None, "a new session without a scenario or a plan is refused above"
            config, changed = lab.study_config(stand_in, seed or 0), None
            creation.enter_context(writer_lock.creating_participant(study))
            assignment = None if lab.study is None else PlanStatus.of(
                lab.study, plan_participants(stored_configs(study))).next
            if scenario is None:  # run-session or serve without --scenario: the plan's proposal
                if assignment is None:
                    raise RefusedAction(f"participant {code!r} has no session yet and every "
                                        "session of the study plan is created: choose a scenario")
                scenario = assignment.proposed
            config = config.model_copy(update={
                "scenario": scenario, "assignment": assignment,
                "seed": choose_seed(study, seed, confirm_seed_reuse)})
        lock = writer_lock.reserve(participant_path(study, code))
        try:
            devices = open_rig(config)
            engine = (SessionEngine.resume(study, code) if exists else
                      SessionEngine.create(study, code, config))
        except BaseException:
            lock.release()
            raise
    return Opened(engine, lock, devices, changed)

"""``handover doctor STUDY_DIR``: a plain verdict on every participant database of a study.

Per file: SQLite's integrity check, the schema version, the participant's code against the file
name, the event log replayed through the protocol (every event parsed and checked against the state
before it: an interaction completed twice, a placement for an unknown trial, …), the stored plan
(seed, counts) against the one the log's session_created records, every table derived from the log
against what the log implies (:mod:`app.protocol.derived`: which rows differ, are missing or have no
event), each trial's safety record taken again from its samples, the derived tables' consistency,
and who holds the writer's lock. Nothing is written: the files are opened read-only and nothing is
migrated.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ValidationError

from app.protocol.derived import differences
from app.protocol.errors import EventLogError
from app.protocol.plan import protocol_slots
from app.protocol.safety_record import rebuilt_differences
from app.protocol.state import Step, replay
from app.protocol.study_config import StudyConfig
from session_store.errors import LockRefused
from session_store.integrity import inspect_database
from session_store.lock import holder_of
from session_store.models import SafetyRecord
from session_store.paths import participant_files
from session_store.sample_rows import read_samples
from session_store.schema import SCHEMA_VERSION


class Verdict(BaseModel):
    """One file's verdict: ``problems`` and ``contradictions`` make it bad; ``notes`` are for
    information."""

    path: Path
    problems: list[str] = []
    #: the problems the event log shows (a log that breaks the protocol, a plan or a table that
    #: differs from it): a file that reads as a database all the same, which export and report
    #: would take as it is
    contradictions: list[str] = []
    notes: list[str] = []

    @property
    def ok(self) -> bool:
        return not self.problems and not self.contradictions

    def text(self) -> str:
        head = f"{self.path.name}: {'OK' if self.ok else 'BAD'}"
        return "\n".join([head, *(f"  problem: {p}" for p in [*self.problems, *self.contradictions]),
                          *(f"  {n}" for n in self.notes)])


def examine(path: Path) -> Verdict:
    """The verdict on one participant database."""
    found = inspect_database(path)
    verdict = Verdict(path=path, problems=list(found.problems))
    try:
        holder = holder_of(path)
    except LockRefused as exc:  # not a lock file, or not this user's to read: say so, read on
        verdict.notes.append(str(exc))
        holder = None
    if holder is not None:
        verdict.notes.append(f"open for writing now: {holder.describe()}")
    if found.participant is None:
        return verdict
    assert found.schema_version is not None, "the schema version is read before the participant"
    if found.participant.code != path.stem:
        verdict.problems.append(f"holds participant {found.participant.code!r}, not {path.stem!r} "
                                "as its file name says (a copy?)")
    if found.schema_version < SCHEMA_VERSION:
        verdict.notes.append(f"schema version {found.schema_version}: migrated to "
                             f"{SCHEMA_VERSION} when next opened for writing")
    try:
        config = StudyConfig.model_validate(found.participant.config)
    except ValidationError as exc:
        verdict.problems.append(f"stored study configuration is invalid: {exc}")
        return verdict
    try:
        state = replay(protocol_slots(config), found.events)
    except EventLogError as exc:
        verdict.contradictions.append(f"event log breaks the protocol: {exc}")
        return verdict
    created = next((e for e in found.events if e.kind == "session_created"), None)
    if created is not None and created.payload.get("config") != found.participant.config:
        recorded = created.payload.get("config") or {}
        changed = sorted(k for k in recorded.keys() | found.participant.config.keys()
                         if recorded.get(k) != found.participant.config.get(k))
        verdict.contradictions.append(f"the stored plan differs from the one the session_created "
                                      f"event records, in {', '.join(changed)}")
    verdict.contradictions += differences(found.tables, found.events)
    records = {e.payload["trial_index"]: SafetyRecord.model_validate(e.payload["safety"])
               for e in found.events if e.kind == "trial_ended" and e.payload.get("safety")}
    verdict.contradictions += rebuilt_differences(records, read_samples(path, list(records)))
    where = "complete" if state.step is Step.DONE else f"waiting for '{state.step.value}'"
    verdict.notes.append(f"seed {config.seed}, {config.scenario.value}; {state.completed} of "
                         f"{state.interactions} interactions completed, {where}; "
                         f"{len(found.events)} events replayed")
    return verdict


def examine_study(study_dir: Path) -> list[Verdict]:
    """Verdicts on every ``*.sqlite`` file of ``study_dir``, by name."""
    return [examine(path) for path in participant_files(study_dir)]


def contradicted(study_dir: Path) -> dict[Path, str]:
    """path → why, for every participant whose event log contradicts its file (doctor's BAD for a
    file that reads as a database all the same): what ``export`` and ``report`` leave out unless
    told ``--force``. A file that cannot be read at all they leave out themselves."""
    return {verdict.path: (f"handover doctor finds it BAD: {verdict.contradictions[0]}"
                           + (f" (and {len(verdict.contradictions) - 1} more)"
                              if len(verdict.contradictions) > 1 else "")
                           + "; --force includes it")
            for verdict in examine_study(study_dir) if verdict.contradictions}

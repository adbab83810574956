"""The handover cycle of one trial as one table (docs/controller.md, "The handover cycle"): every stage in
order, with when it begins (its entry condition), the experimenter's confirmation it may wait for (its
gate), what the rig does in it and when it ends (its exit).

The rig runs the table. :func:`robot_io.control.cycle.run_cycle` goes through the stages before Go row
by row: it waits for the row's entry condition, reports the stage, does its work, waits for its gate
and does its exit work; :class:`robot_io.control.loop.HandoverLoop` runs the streamed stages, one step
per control cycle. The application reads what it shows from the same rows: the stage a trial waits in
and the dashboard's button for it (:attr:`StageRow.gate`), the dashboard's words (:attr:`StageRow.says`),
the tablet's screen (:attr:`StageRow.part`), the names of the stored ``trial_stage`` events and the
report's table of the cycle.

A new confirmed stage before Go (say "wait for gaze") is one row of :data:`PAPER_CYCLE`, in its place,
with a :class:`Confirmation`: the rig waits for it, the dashboard shows its button and words, the
session stores it and the report counts it. To run one for a while (a lab's pilot, a test),
:func:`extended` adds it to the cycle the application runs until its ``with`` block ends; a rig runs
the cycle it was opened with (``RigSpec.cycle``).
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from enum import StrEnum
from typing import Annotated

from pydantic import Field, StringConstraints, model_validator

from robot_io.bounds import Frozen

#: A stage's name as messages, events and sample rows carry it: lower case, words joined by "_".
StageName = Annotated[str, StringConstraints(pattern=r"^[a-z][a-z_]*$", max_length=40)]


class Stage(StrEnum):
    """The names of the paper's cycle (Fig. 1): the rows of :data:`PAPER_CYCLE`."""

    PREPARE = "prepare"
    LOADED = "loaded"
    READY = "ready"
    GO = "go"
    REACH = "reach"
    HOLD = "hold"
    RELEASE = "release"
    NOT_TAKEN = "not_taken"
    RETRACT = "retract"
    DONE = "done"


class Part(StrEnum):
    """Where in the trial a stage lies, which says who runs it and what the participant sees."""

    BEFORE_GO = "before_go"  # run_cycle, nothing streams; the tablet asks to wait
    STREAMED = "streamed"  # the control loop, one sample row per cycle; the tablet shows "Go!"
    AFTER = "after"  # the stream has ended; the tablet says the robot moves back


class Work(StrEnum):
    """What the rig does in a stage before Go (robot_io.control.cycle implements each one)."""

    MOVE_TO_START = "move_to_start"  # bounded move to R ([ur] max_move_distance), the gripper open
    CLOSE_GRIPPER = "close_gripper"  # the gripper closes on the object
    HAND_AT_START = "hand_at_start"  # wait: tracker live, hand within [cycle] start_zone_m of A


class Confirmation(Frozen):
    """A gate: the experimenter's confirmation a stage waits for before it ends (given at once by
    the simulated participant and the simulated experimenter)."""

    button: str = Field(description="the dashboard's button that gives it")
    asks: str = Field(description="the dashboard's status line while the cycle waits for it (Markdown)")


class StageRow(Frozen):
    """One stage of the cycle."""

    name: StageName
    part: Part
    entry: str = Field(description="when it begins, in words")
    does: str = Field(description="what the rig does in it, in words")
    exit: str = Field(description="when it ends, in words")
    says: str = Field(description="the dashboard's words while it runs: 'Handover running — …'")
    gate: Confirmation | None = Field(None, description="the confirmation it waits for")
    awaits: Work | None = Field(None, description="the condition the rig waits for before it begins")
    work: Work | None = Field(None, description="what the rig does once it began, before its gate")
    then: Work | None = Field(None, description="what the rig does after its gate, as it ends")
    sample_code: float | None = Field(None, description="its value in the samples' stage column")
    instead_of: StageName | None = Field(None, description="the stage whose place it takes in the "
                                                           "dashboard's cycle line")

    @model_validator(mode="after")
    def _work_before_go(self) -> StageRow:
        """The experimenter confirms, and the rig waits or moves to R, only before the cue: nothing
        holds the arm up while it streams towards a person."""
        if self.part is not Part.BEFORE_GO and (self.gate or self.awaits or self.work or self.then):
            raise ValueError(f"stage {self.name!r}: a gate and work of run_cycle belong to a stage "
                             "before Go")
        return self


class CycleTable(Frozen):
    """The stages of one trial in order: those before Go, then the streamed ones from ``go``, then
    those after the stream."""

    rows: tuple[StageRow, ...]

    @model_validator(mode="after")
    def _in_order(self) -> CycleTable:
        names = [row.name for row in self.rows]
        if len(set(names)) != len(names):
            raise ValueError(f"a stage is listed twice: {names}")
        parts = [row.part for row in self.rows]
        if parts != sorted(parts, key=list(Part).index):
            raise ValueError(f"the stages before Go come first, then the streamed ones, then those "
                             f"after: {list(zip(names, parts, strict=True))}")
        streamed = [row.name for row in self.rows if row.part is Part.STREAMED]
        if not streamed or streamed[0] != Stage.GO:
            raise ValueError(f"the streamed stages begin with {Stage.GO.value!r}: {streamed}")
        for row in self.rows:
            if row.instead_of is not None and row.instead_of not in names:
                raise ValueError(f"stage {row.name!r} stands instead of {row.instead_of!r}, which "
                                 "is no stage")
        return self

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(row.name for row in self.rows)

    def row(self, name: str) -> StageRow:
        for row in self.rows:
            if row.name == name:
                return row
        raise KeyError(f"{name!r} is no stage of the cycle; the stages are {', '.join(self.names)}")

    @property
    def before_go(self) -> tuple[StageRow, ...]:
        return tuple(row for row in self.rows if row.part is Part.BEFORE_GO)

    @property
    def streamed(self) -> frozenset[str]:
        """The stages during which the rig writes one sample row per control cycle."""
        return frozenset(row.name for row in self.rows if row.part is Part.STREAMED)

    @property
    def gated(self) -> tuple[StageRow, ...]:
        """The stages that wait for the experimenter, in order."""
        return tuple(row for row in self.rows if row.gate is not None)

    def gate(self, name: str | None) -> Confirmation | None:
        """The confirmation stage ``name`` waits for (None: none, or no such stage)."""
        return next((row.gate for row in self.rows if row.name == name), None)

    def sample_code(self, name: str) -> float | None:
        return self.row(name).sample_code

    def with_row(self, row: StageRow, before: str) -> CycleTable:
        """This cycle with ``row`` inserted before the stage ``before``."""
        self.row(before)  # a stage of this cycle
        at = self.names.index(before)
        return CycleTable(rows=(*self.rows[:at], row, *self.rows[at:]))


def _loaded_gate() -> Confirmation:
    return Confirmation(button="Object loaded",
                        asks="**Load the object** into the gripper, then press **Object loaded**.")


#: The paper's cycle (Fig. 1, docs/controller.md): prepare → loaded → ready → go → reach → hold →
#: release (or not_taken) → retract → done.
PAPER_CYCLE = CycleTable(rows=(
    StageRow(name=Stage.PREPARE, part=Part.BEFORE_GO, entry="Start trial",
             does="moves to R at bounded speed, the gripper open; the object goes into it",
             exit="Object loaded: the gripper closes", says="the robot moves to its start",
             gate=_loaded_gate(), work=Work.MOVE_TO_START, then=Work.CLOSE_GRIPPER),
    StageRow(name=Stage.LOADED, part=Part.BEFORE_GO, entry="the gripper closed on the object",
             does="waits for the hand at the start", exit="the hand is ready",
             says="the object is loaded"),
    StageRow(name=Stage.READY, part=Part.BEFORE_GO,
             entry="the tracker is live and the hand within [cycle] start_zone_m of A (within "
                   "[cycle] ready_timeout_s)", does="waits for Go", exit="Go",
             says="the participant's hand is at the start", awaits=Work.HAND_AT_START,
             gate=Confirmation(button="Go",
                               asks="**The participant's hand is at the start** — press **Go**.")),
    StageRow(name=Stage.GO, part=Part.STREAMED, entry="Go: t = 0, the tablet shows Go!",
             does="streams, waiting for a hand sample", exit="the first servo target is sent",
             says="Go given"),
    StageRow(name=Stage.REACH, part=Part.STREAMED, entry="the first servo target is sent",
             does="the coupled DMP towards H (eqs. 1–10)",
             exit="the robot within robot_arrival_tolerance_m of H, slower than [cycle] "
                  "hold_settle_speed", says="the robot reaches out", sample_code=1.0),
    StageRow(name=Stage.HOLD, part=Part.STREAMED, entry="the robot at H and still",
             does="k_ext compliance; the force baseline over [release] baseline_s, then the "
                  "release is armed",
             exit="a pull ≥ [release] threshold_n (release), or none within [release] timeout_s "
                  "(not_taken)", says="the robot holds the object out", sample_code=2.0),
    StageRow(name=Stage.RELEASE, part=Part.STREAMED, entry="the pull passed the threshold",
             does="the gripper opens; the arm keeps still", exit="[cycle] release_linger_s later",
             says="the gripper opens", sample_code=3.0),
    StageRow(name=Stage.NOT_TAKEN, part=Part.AFTER, entry="no pull within [release] timeout_s",
             does="the gripper stays closed: the robot keeps the object", exit="at once",
             says="nobody took the object", instead_of=Stage.RELEASE),
    StageRow(name=Stage.RETRACT, part=Part.AFTER, entry="the handover ended (released or not taken)",
             does="moves back to R at bounded speed", exit="the robot is at R",
             says="the robot moves back"),
    StageRow(name=Stage.DONE, part=Part.AFTER, entry="the robot is back at R",
             does="nothing: the cycle is over", exit="—", says="the robot is back"),
))

_lock = threading.Lock()
_current = PAPER_CYCLE


def current() -> CycleTable:
    """The cycle the application runs: :data:`PAPER_CYCLE`, or the one :func:`extended` made."""
    return _current


@contextmanager
def extended(row: StageRow, before: str) -> Iterator[CycleTable]:
    """The cycle with ``row`` before the stage ``before``, as the one the application runs until the
    ``with`` block ends (the extension point for a stage of one's own: a pilot's, a test's). A rig
    runs the cycle it was opened with: open it inside the block."""
    global _current
    with _lock:
        previous = _current
        _current = previous.with_row(row, before)
    try:
        yield _current
    finally:
        with _lock:
            _current = previous


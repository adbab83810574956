"""What the two screens say in each stage of the handover cycle (:class:`robot_io.stages.Stage`, the
cycle's order): the one table of it. A stage added to the cycle gets its line here, in its place;
``tests/ui/test_stage_words.py`` fails until it has one.

The tablet shows one of three screens while a trial runs: "Please wait" before Go (the session's
next step decides what it says), "Go!" from the cue until the gripper opens, "One moment — the robot
is moving back" after the hold. The dashboard's status line says what the robot does, in words, and
its cycle line draws the stages in order with the current one in bold.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

from robot_io.stages import Stage

#: The tablet's screen during a stage: "wait" (what the session's step shows: please wait),
#: "go" (the cue, with a beep), "back" (the robot moves back).
TabletScreen = Literal["wait", "go", "back"]


class StageWords(NamedTuple):
    """One stage as the tablet and the dashboard show it."""

    tablet: TabletScreen
    dashboard: str  # "Handover running — {dashboard}."


#: Every stage in the cycle's order. ``not_taken`` stands in ``release``'s place when nobody pulls.
STAGE_WORDS: dict[Stage, StageWords] = {
    Stage.PREPARE: StageWords("wait", "the robot moves to its start"),
    Stage.LOADED: StageWords("wait", "the object is loaded"),
    Stage.READY: StageWords("wait", "the participant's hand is at the start"),
    Stage.GO: StageWords("go", "Go given"),
    Stage.REACH: StageWords("go", "the robot reaches out"),
    Stage.HOLD: StageWords("go", "the robot holds the object out"),
    Stage.RELEASE: StageWords("go", "the gripper opens"),
    Stage.NOT_TAKEN: StageWords("back", "nobody took the object"),
    Stage.RETRACT: StageWords("back", "the robot moves back"),
    Stage.DONE: StageWords("back", "the robot is back"),
}
#: The stage whose place another takes in the dashboard's cycle line (the two ends of a hold).
INSTEAD_OF = {Stage.NOT_TAKEN: Stage.RELEASE}
#: The handover cycle as the dashboard draws it: every stage but those that take another's place.
CYCLE: tuple[Stage, ...] = tuple(s for s in STAGE_WORDS if s not in INSTEAD_OF)


def stage_name(stage: Stage) -> str:
    """The stage as the cycle line names it: "not taken"."""
    return stage.value.replace("_", " ")

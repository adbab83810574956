"""What the two screens say in each stage of the handover cycle, read from the cycle's table
(:mod:`robot_io.control.stages`, the cycle's order): a stage's row gives its dashboard words, and its
part of the cycle the tablet's screen. A stage added to the table is shown with its own words.

The tablet shows one of three screens while a trial runs: "Please wait" before Go (the session's
next step decides what it says), "Go!" from the cue until the gripper opens, "One moment — the robot
is moving back" after the hold. The dashboard's status line says what the robot does, in words, and
its cycle line draws the stages in order with the current one in bold.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

from robot_io.control.stages import Part, Stage, current

#: The tablet's screen during a stage: "wait" (what the session's step shows: please wait),
#: "go" (the cue, with a beep), "back" (the robot moves back).
TabletScreen = Literal["wait", "go", "back"]
#: The tablet's screen in each part of the cycle: before Go, streaming, after the stream.
SCREENS: dict[Part, TabletScreen] = {Part.BEFORE_GO: "wait", Part.STREAMED: "go", Part.AFTER: "back"}


class StageWords(NamedTuple):
    """One stage as the tablet and the dashboard show it."""

    tablet: TabletScreen
    dashboard: str  # "Handover running — {dashboard}."


def stage_words(stage: str) -> StageWords:
    """The words of ``stage`` in the cycle the application runs."""
    row = current().row(stage)
    return StageWords(SCREENS[row.part], row.says)


def instead_of() -> dict[str, str]:
    """The stage whose place another takes in the dashboard's cycle line (the two ends of a hold)."""
    return {row.name: row.instead_of for row in current().rows if row.instead_of is not None}


def cycle_line() -> tuple[str, ...]:
    """The handover cycle as the dashboard draws it: every stage but those that take another's place."""
    return tuple(row.name for row in current().rows if row.instead_of is None)


def before_ready(stage: str | None) -> bool:
    """Whether ``stage`` comes before the hand is awaited at the start (``ready``)."""
    names = current().names
    return stage in names and names.index(str(stage)) < names.index(Stage.READY)


def stage_name(stage: str) -> str:
    """The stage as the cycle line names it: "not taken"."""
    return stage.replace("_", " ")

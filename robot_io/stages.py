"""The stages of one handover cycle (docs/controller.md), in order; each is reported and recorded when it
begins. ``release`` and ``not_taken`` are the two ways a hold ends. The tablet's and the dashboard's
words for each stage are in ``app/ui/stage_words.py``."""

from __future__ import annotations

from enum import StrEnum
from typing import Literal


class Stage(StrEnum):
    PREPARE = "prepare"  # bounded move to the start pose R; the object goes into the gripper
    LOADED = "loaded"  # confirmed loaded (automatic in simulation): the gripper has closed on it
    READY = "ready"  # tracker alive and the hand inside the start zone around A
    GO = "go"  # the tablet's cue; the trial clock starts (t = 0)
    REACH = "reach"  # the first servo target of the coupled DMP is sent
    HOLD = "hold"  # the robot is at H and still: k_ext compliance, release armed
    RELEASE = "release"  # the pull passed the threshold: the gripper opens
    NOT_TAKEN = "not_taken"  # no pull within the release timeout: the robot keeps the object
    RETRACT = "retract"  # bounded move back to R
    DONE = "done"  # back at R: the cycle is over


#: The experimenter's confirmation the cycle waits for in a stage (:class:`robot_io.control.cycle.Gates`).
AWAITS: dict[Stage, Literal["loaded", "go"]] = {Stage.PREPARE: "loaded", Stage.READY: "go"}

#: The value of the ``stage`` sample column in each streamed stage.
SAMPLE_CODE = {Stage.REACH: 1.0, Stage.HOLD: 2.0, Stage.RELEASE: 3.0}

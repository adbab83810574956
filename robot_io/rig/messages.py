"""The typed messages between the application and the rig process (one pipe each way).

Application → rig: :class:`RunTrial`, :class:`Gate` (the experimenter's confirmation a stage of the
cycle waits for: Object loaded, Go, …), :class:`Stop`,
:class:`Recover`, :class:`Shutdown`, and a :class:`Heartbeat` every ``HEARTBEAT_S``: a rig whose
application is stopped by a signal, or sends nothing for ``APP_SILENCE_S``, during a trial on the
wall clock stops the arm.
Rig → application: :class:`RigOpened` or :class:`RigFailed` once, then per trial
:class:`StageReached` for each stage, :class:`ReadyWaiting` while the hand is not at A, and
:class:`TrialDone` with the summary; :class:`Recovered` answers a :class:`Recover`;
:class:`StopReceived` acknowledges a stop at once; :class:`RigTiming` says that a trial's cycles or
hand samples run late; :class:`HandLink` whenever what the tracked hand's link went through
changes (unreadable packets dropped, lost and back). Samples do not travel here: the rig writes
them into shared memory (:mod:`robot_io.rig.stream`).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from robot_io.config import ControllerConfig
from robot_io.control.loop import TrialSummary
from robot_io.control.stages import CycleTable, StageName, current
from robot_io.hands.simulated_hand import Scenario
from robot_io.theta import Theta

#: The application sends a :class:`Heartbeat` this often [s].
HEARTBEAT_S = 0.1
#: A rig that hears nothing from the application for this long while a trial runs on the wall clock
#: stops the arm and ends the trial 'stopped' [s]: the application hangs and nothing else could stop
#: the arm. An application *stopped* by a signal (Ctrl-Z in its terminal, SIGSTOP, a debugger) is
#: seen at once in its process state, without waiting for this (robot_io.rig.process). The bound is
#: not shorter because a running application's heartbeat thread needs the interpreter's lock: under
#: the test suite's load (3 workers on 2 cores) a thread at normal priority that held it was kept
#: off the CPU long enough for 0.5 s of silence in a live session (a false stop, seen in a full run).
#: Time the rig itself was not run (the machine held still) is not counted (robot_io.rig.process).
APP_SILENCE_S = 2.0


class _Message(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class RigSpec(_Message):
    """What the rig process opens and how it keeps time."""

    config: ControllerConfig
    scenario: Scenario | None = Field(None, description="the simulated hand's scenario (simulated "
                                                        "hand source only)")
    realtime: bool = Field(True, description="wall clock; False: simulated time (mock arm and "
                                             "simulated hand only)")
    realtime_priority: bool = Field(False, description="run the rig under SCHED_FIFO where the OS "
                                                       "permits it (wall clock only), as resolved "
                                                       "at start from [loop] realtime_priority")
    cycle: CycleTable = Field(default_factory=current, description="the handover cycle the rig runs "
                                                                  "(robot_io.control.stages)")


# -- application → rig ---------------------------------------------------------------------------
class RunTrial(_Message):
    kind: Literal["run_trial"] = "run_trial"
    trial_index: int
    theta: Theta | None
    hand_seed: int
    automatic: bool = Field(description="every confirmation of the cycle counts as given (the "
                                        "simulated participant, the simulated experimenter)")


class Gate(_Message):
    """The experimenter's confirmation that ``stage`` waits for (its row's gate: Object loaded in
    prepare, Go in ready, …); ignored in any other stage."""

    kind: Literal["gate"] = "gate"
    stage: StageName


class Stop(_Message):
    kind: Literal["stop"] = "stop"
    reason: str


class Recover(_Message):
    """Clear an arm fault (moves nothing). ``inspected``: someone inspected the cause, as a
    protective or emergency stop requires; without it only other faults are cleared."""

    kind: Literal["recover"] = "recover"
    inspected: bool


class Shutdown(_Message):
    kind: Literal["shutdown"] = "shutdown"


class Heartbeat(_Message):
    """The application is alive and its watcher reads the rig's sample stream."""

    kind: Literal["heartbeat"] = "heartbeat"


Command = RunTrial | Gate | Stop | Recover | Shutdown | Heartbeat


# -- rig → application ---------------------------------------------------------------------------
class DeviceReport(_Message):
    """The devices the rig actually opened, in words and in fields (stored with the session)."""

    arm: str = Field(description="mock or ur")
    arm_detail: str = Field(description="e.g. 'UR at 127.0.0.5, PolyScope 3.15.7, 125 Hz'")
    polyscope_version: str | None = None
    rate_hz: int
    hand_source: str = Field(description="[hand_source] kind (robot_io.hands.config.HAND_SOURCES)")
    hand_detail: str
    gripper: str = Field(description="none, tool_output or robotiq_socket")
    gripper_detail: str
    realtime_priority: bool = Field(False, description="the rig's threads run under SCHED_FIFO (its "
                                                       "control loop above them during a trial)")


class RigOpened(_Message):
    kind: Literal["rig_opened"] = "rig_opened"
    devices: DeviceReport
    pid: int


class RigFailed(_Message):
    kind: Literal["rig_failed"] = "rig_failed"
    reason: str


class StageReached(_Message):
    kind: Literal["stage"] = "stage"
    trial_index: int
    stage: StageName
    t: float | None = Field(description="trial time since Go [s]; None before Go")
    monotonic: float = Field(description="time.monotonic() of this machine when it began")


class ReadyWaiting(_Message):
    kind: Literal["ready_waiting"] = "ready_waiting"
    trial_index: int
    why: str | None = Field(description="why the hand is not ready; None: it is")


class StopReceived(_Message):
    kind: Literal["stop_received"] = "stop_received"


class Recovered(_Message):
    kind: Literal["recovered"] = "recovered"
    ok: bool
    message: str


class TrialDone(_Message):
    kind: Literal["trial_done"] = "trial_done"
    trial_index: int
    summary: TrialSummary
    rows: int = Field(description="sample rows written to the shared stream")


class RigTiming(_Message):
    """The running trial's timing is degraded (robot_io.rig.timing): its worst so far, sent as soon as
    it passes a bound and again (at most every second) while it grows."""

    kind: Literal["rig_timing"] = "rig_timing"
    trial_index: int
    late_cycles: int = Field(description="control cycles that started more than late_bound_s late")
    latest_start_s: float = Field(description="the latest of those starts, after its schedule [s]")
    late_bound_s: float
    oldest_hand_sample_s: float = Field(description="the oldest hand sample a cycle steered by [s]")
    old_bound_s: float
    staleness_limit_s: float = Field(description="[loop] staleness_limit_s: the tracker is lost")
    realtime_priority: bool = Field(description="the rig runs under SCHED_FIFO")
    final: bool = Field(False, description="the whole trial's figures, sent at its end (else the "
                                           "trial's so far)")

    def describe(self) -> str:
        """What ran late and by how much, and what to do about it, in the experimenter's words:
        the trial's figures so far, or the whole trial's (:attr:`final`)."""
        parts = []
        if self.late_cycles:
            cycles = "1 control cycle" if self.late_cycles == 1 else \
                f"{self.late_cycles} control cycles"
            parts.append(f"{cycles} started late, by up to "
                         f"{self.latest_start_s * 1e3:.0f} ms (warned above "
                         f"{self.late_bound_s * 1e3:.0f} ms)")
        if self.oldest_hand_sample_s > self.old_bound_s:
            parts.append(f"the hand samples it steered by were up to "
                         f"{self.oldest_hand_sample_s * 1e3:.0f} ms old (the tracker counts as lost "
                         f"at {self.staleness_limit_s * 1e3:.0f} ms)")
        advice = ("the machine is too busy even for the rig's real-time priority: close other "
                  "programs" if self.realtime_priority else
                  "the rig runs without real-time priority: grant it (docs/hardware.md, "
                  "\"Real-time priority\") or close other programs")
        when = "" if self.final else " so far"
        return f"timing degraded in trial {self.trial_index}{when}: {'; '.join(parts)} — {advice}"


class HandLink(_Message):
    """What the tracked hand's link to its tracker went through, in one line
    (:meth:`robot_io.hands.tracked_hand.Link.notice`), sent each time it changes."""

    kind: Literal["hand_link"] = "hand_link"
    notice: str


class RigDied(_Message):
    """Made by the application's client, not sent: the rig process ended without being told to."""

    kind: Literal["rig_died"] = "rig_died"
    trial_index: int | None
    reason: str


Report = (RigOpened | RigFailed | StageReached | ReadyWaiting | StopReceived | Recovered
          | TrialDone | RigTiming | HandLink)

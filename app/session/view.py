"""What a screen shows of the running session (:class:`RunnerView`), built from state by pure
functions: :func:`build_view` from the engine's facts and the status beside them, :func:`with_news`
from a view already shown and newer status (device news, published without the engine thread).

Nothing here reads a device, the engine or the clock; the session runner gathers the inputs, each on
the thread that owns it (docs/architecture.md, "Threads and who owns what")."""

from __future__ import annotations

from typing import Literal, NamedTuple

from pydantic import BaseModel, ConfigDict

from app.learning.models import PosteriorSlice
from app.protocol.design import PlanStatus
from app.protocol.state import SessionState, Step
from app.session.overview import ParticipantSummary
from app.session.pairing import TabletStatus
from app.session.recording import RecordingStatus
from robot_io.control.stages import StageName, current
from robot_io.hands.simulated_hand import Scenario
from robot_io.rig.messages import DeviceReport, RigTiming
from session_store.models import Trial

#: After STOP ARM: "stopping" until the arm has stopped (the running trial has ended), then
#: "stopped" until the experimenter re-arms (the scene is safe); only "armed" lets a trial start.
StopState = Literal["armed", "stopping", "stopped"]


class ThetaStar(BaseModel):
    after_interaction: int
    a: float
    delta: float
    k: float


class RunnerView(BaseModel):
    """Everything a screen shows, copied at one moment. ``state`` is None before a session is open."""

    model_config = ConfigDict(frozen=True)

    version: int = 0
    code: str | None = None
    scenario: Scenario | None = None
    seed: int | None = None
    state: SessionState | None = None
    preparing: bool = False
    auto: bool = False
    rehearsal: bool = False
    refusing_object: bool = False  # a rehearsal's simulated participant does not take the object
    arm: str = "no rig open"
    arm_fault: str | None = None
    hand: str = ""
    hand_link: str | None = None  # what the tracked hand's link went through (None: nothing)
    gripper: str = ""
    timing: str = ""  # the rig's scheduling: real-time priority or not
    timing_warning: str | None = None  # the latest trial's cycles or hand samples ran late: how
    waiting_for: StageName | None = None  # the stage that waits for the experimenter's confirmation
    ready_wait: str | None = None  # why the hand is not ready at the start A
    learner: str = "idle"
    learner_fault: str | None = None
    failed: str | None = None  # the simulated experimenter gave up (headless), or storing failed: why
    stop: StopState = "armed"
    tablet: TabletStatus | None = None  # None: no tablet screen (headless)
    tablet_required: bool = True  # exactly one paired tablet before a trial may start
    overview: list[ParticipantSummary] = []  # every participant of the study folder
    plan: PlanStatus | None = None  # the study against its plan ([study]; None: no plan)
    messages: list[str] = []  # the latest events, newest last
    trials: list[Trial] = []
    theta_star: list[ThetaStar] = []
    posterior: list[PosteriorSlice] = []  # posterior utility through θ*, per parameter
    learning: str | None = None  # how settled the learner's θ* is, in words (after a learning batch)
    safety_flags: list[str] = []  # the trials over the lab's [safety_record] limits, in words
    recording: RecordingStatus | None = None  # the session's XDF recording ([recording]; None: none)

    @property
    def step(self) -> Step | None:
        return None if self.state is None else self.state.step

    @property
    def interactions(self) -> int:
        """The interactions of the open session's plan as it stands now (0: none open)."""
        return 0 if self.state is None else self.state.interactions

    @property
    def stage(self) -> str | None:
        return None if self.state is None else self.state.stage


class RigStatus(NamedTuple):
    """The trial supervisor's state at one moment (:class:`app.session.supervisor.TrialSupervisor`)."""

    devices: DeviceReport | None = None  # None: no rig process open
    fault: str | None = None  # the arm's fault, until recovered
    timing: RigTiming | None = None  # the latest late timing, until a trial runs on time
    hand_link: str | None = None
    ready_wait: str | None = None
    stop: StopState = "armed"


class Status(NamedTuple):
    """The view's fields that do not come from the engine, gathered without its thread."""

    rig: RigStatus
    realtime: bool
    rehearsal: bool
    refusing_object: bool
    preparing: bool
    learner_fault: str | None
    failed: str | None
    tablet: TabletStatus | None
    tablet_required: bool
    messages: list[str]
    auto: bool
    recording: RecordingStatus | None = None


class SessionFacts(NamedTuple):
    """What the view shows of the open session, read from the engine on its thread."""

    code: str
    scenario: Scenario
    seed: int
    state: SessionState  # a copy: the engine goes on changing its own
    trials: list[Trial]
    theta_star: list[ThetaStar]
    posterior: list[PosteriorSlice]
    learning: str | None  # app.protocol.learning_words.learning_line
    safety_flags: list[str]  # the trials over the lab's limits (app.protocol.safety_record)


def timing_words(devices: DeviceReport | None, realtime: bool) -> str:
    """The rig's scheduling in words: under real-time priority or not (nothing without a rig)."""
    if devices is None:
        return ""
    if not realtime:
        return "simulated time"
    return ("real-time priority (SCHED_FIFO)" if devices.realtime_priority else
            "no real-time priority (normal scheduling): trials may run late on a busy machine")


def waiting_for(state: SessionState, automatic: bool) -> str | None:
    """The running trial's stage if it waits for the experimenter's confirmation (its gate in the
    cycle's table: Object loaded in prepare, Go in ready); nothing when the trials confirm
    themselves (``automatic``)."""
    if automatic or state.step is not Step.RUNNING or current().gate(state.stage) is None:
        return None
    return state.stage


def status_fields(status: Status) -> dict:
    """The view's fields from ``status``."""
    rig, devices = status.rig, status.rig.devices
    return {"arm": "no rig open" if devices is None else devices.arm_detail,
            "hand": "" if devices is None else devices.hand_detail, "hand_link": rig.hand_link,
            "gripper": "" if devices is None else devices.gripper_detail,
            "timing": timing_words(devices, status.realtime),
            "timing_warning": None if rig.timing is None else rig.timing.describe(),
            "arm_fault": rig.fault, "rehearsal": status.rehearsal,
            "refusing_object": status.refusing_object,
            "learner": "fitting the next θ" if status.preparing else "idle",
            "learner_fault": status.learner_fault, "failed": status.failed,
            "ready_wait": rig.ready_wait, "stop": rig.stop, "tablet": status.tablet,
            "tablet_required": status.tablet_required, "messages": list(status.messages),
            "auto": status.auto, "recording": status.recording}


def build_view(version: int, status: Status, overview: list[ParticipantSummary],
               session: SessionFacts | None, auto_experimenter: bool,
               plan: PlanStatus | None = None) -> RunnerView:
    """The view numbered ``version``: the open ``session`` (None: none open) beside ``status``,
    the study's ``overview`` and where it stands against its ``plan``.
    The cycle waits for the experimenter only when neither the simulated participant
    (``status.auto``) nor the simulated experimenter (``auto_experimenter``) confirms it."""
    fields = {**status_fields(status), "overview": overview, "plan": plan}
    if session is None:
        return RunnerView(version=version, **fields)
    return RunnerView(
        version=version, code=session.code, scenario=session.scenario, seed=session.seed,
        state=session.state, preparing=status.preparing,
        waiting_for=waiting_for(session.state, status.auto or auto_experimenter),
        trials=session.trials, theta_star=session.theta_star, posterior=session.posterior,
        learning=session.learning, safety_flags=session.safety_flags, **fields)


def with_news(view: RunnerView, status: Status) -> RunnerView:
    """``view`` (the engine's part as it was shown) with newer ``status``: device news published
    without waiting for the engine thread."""
    return view.model_copy(update=status_fields(status))

"""The trial supervisor's stop states on a real rig process (mock arm, simulated hand): a Stop
that lands between Start's check and the trial reaching the rig keeps the trial from the arm, and a
trial the experimenter stopped is recorded as theirs, with Start refused until Re-arm."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest
from support.waiting import wait_for

from app.protocol.engine import TrialPlan
from app.protocol.errors import RefusedAction
from app.session.supervisor import STOP_REASON, Recording, TrialSupervisor
from robot_io.config import ControllerConfig
from robot_io.control.stages import Stage
from robot_io.hands.simulated_hand import Scenario
from robot_io.theta import Theta
from session_store.models import Trial
from session_store.vocabulary import Actor, Phase, ThetaOrigin

THETA = Theta(a=5.0, delta=-0.2, k=5.0)
PLAN = TrialPlan(trial=Trial(trial_index=1, interaction=1, attempt=1, phase=Phase.INITIAL, batch=0,
                             position=1, theta_a=THETA.a, theta_delta=THETA.delta, theta_k=THETA.k,
                             origin=ThetaOrigin.SOBOL, hand_seed=7,
                             started_at="2026-01-01T00:00:00+00:00"),
                 theta=THETA)


class Session:
    """What the session records of the supervisor's reports (the runner does this on its engine
    thread): the stages reached, the trials' ends with their reasons and actors, the messages."""

    def __init__(self) -> None:
        self.stages: list[Stage] = []
        self.ends: list[tuple[int, str | None, Actor]] = []
        self.messages: list[str] = []
        self.lock = threading.Lock()

    def recording(self) -> Recording:
        return Recording(stage=lambda report: self._add(self.stages, report.stage),
                         trial_end=self._trial_end, outlets=lambda: None,
                         changed=self._message, news=self._message)

    def _add(self, items: list, item: object) -> None:
        with self.lock:
            items.append(item)

    def _trial_end(self, trial_index, record, reason, actor) -> None:
        self._add(self.ends, (trial_index, reason, actor))

    def _message(self, message: str | None) -> None:
        if message is not None:
            self._add(self.messages, message)


@pytest.fixture
def supervised() -> Iterator[tuple[TrialSupervisor, Session]]:
    """A supervisor with its rig open on the wall clock (a trial lasts seconds)."""
    session = Session()
    supervisor = TrialSupervisor(session.recording(), realtime=True, realtime_priority=True,
                                 rehearsal=None)
    supervisor.open(ControllerConfig(), Scenario.STRAIGHTFORWARD)
    try:
        yield supervisor, session
    finally:
        supervisor.close("the test is over")


def test_a_stop_between_starts_check_and_the_rig_keeps_the_trial_from_the_arm(supervised):
    """The engine thread checks that the arm is armed, records the trial's start, then hands the
    trial to the rig. STOP ARM pressed in between must not let it reach the rig (the runner used
    to send it all the same: the arm moved after STOP ARM)."""
    supervisor, session = supervised
    supervisor.refuse_unless_armed()  # Start's check: armed
    assert supervisor.stop() == "Stop: the arm is stopped"  # pressed before the trial is sent
    with pytest.raises(RefusedAction, match="the arm was stopped"):
        supervisor.run(PLAN, automatic=True)
    assert supervisor.rig.running is None and supervisor.status().stop == "stopped"
    assert session.ends == []


def test_a_trial_stopped_by_the_experimenter_is_theirs_and_start_waits_for_rearm(supervised):
    supervisor, session = supervised
    supervisor.run(PLAN, automatic=True)
    wait_for(lambda: Stage.GO in session.stages, "the trial's Go", seen=lambda: session.stages)
    assert supervisor.stop() in ("STOP ARM: the arm is stopping", "Stop: the arm is stopped")
    wait_for(lambda: session.ends, "the stopped trial's end", seen=lambda: session.messages)
    assert session.ends == [(1, STOP_REASON, Actor.EXPERIMENTER)]
    wait_for(lambda: supervisor.status().stop == "stopped", "the arm stopped",
             seen=supervisor.status)
    with pytest.raises(RefusedAction, match="STOP ARM"):
        supervisor.refuse_unless_armed()
    supervisor.rearm()
    supervisor.refuse_unless_armed()
    with pytest.raises(RefusedAction, match="was not stopped"):
        supervisor.rearm()

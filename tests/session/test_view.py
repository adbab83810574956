"""The view builder is a pure function of state: the open session's facts and the status beside them
give the view a screen shows, and device news changes the status and nothing of the engine's part."""

from __future__ import annotations

import pytest

from app.protocol.plan import protocol_slots
from app.protocol.state import SessionState, Step
from app.session.config import LabConfig
from app.session.view import (
    RigStatus,
    SessionFacts,
    Status,
    ThetaStar,
    build_view,
    timing_words,
    with_news,
)
from robot_io.control.stages import Stage
from robot_io.hands.simulated_hand import Scenario
from robot_io.rig.messages import DeviceReport, RigTiming

DEVICES = DeviceReport(arm="mock", arm_detail="mock arm, 125 Hz", rate_hz=125,
                       hand_source="simulated", hand_detail="simulated hand", gripper="none",
                       gripper_detail="no gripper", realtime_priority=True)
LATE = RigTiming(trial_index=4, late_cycles=3, latest_start_s=0.004, late_bound_s=0.002,
                 oldest_hand_sample_s=0.01, old_bound_s=0.05, staleness_limit_s=0.2,
                 realtime_priority=True)


def status(**changes) -> Status:
    fields = dict(rig=RigStatus(), realtime=True, rehearsal=False, refusing_object=False,
                  preparing=False, learner_fault=None, failed=None, tablet=None,
                  tablet_required=False, messages=[], auto=False)
    return Status(**{**fields, **changes})


def facts(running: int | None, stage: Stage | None) -> SessionFacts:
    config = LabConfig().study_config(Scenario.PERTURBED, 7)
    state = SessionState(slots=protocol_slots(config), running_trial=running, stage=stage)
    return SessionFacts(code="M01", scenario=Scenario.PERTURBED, seed=7, state=state,
                        trials=[],
                        theta_star=[ThetaStar(after_interaction=3, a=1.0, delta=0.5, k=2.0)],
                        posterior=[], learning="the learner's first choice; 45% sure",
                        safety_flags=[])


@pytest.mark.parametrize(("stage", "auto", "auto_experimenter", "expected"), [
    (Stage.PREPARE, False, False, Stage.PREPARE),  # Object loaded
    (Stage.READY, False, False, Stage.READY),  # Go
    (Stage.GO, False, False, None),
    (Stage.PREPARE, True, False, None),  # the simulated participant confirms
    (Stage.READY, False, True, None),  # the simulated experimenter (headless) confirms
])
def test_a_running_trial_waits_for_the_experimenter_only_where_nobody_simulated_confirms(
        stage, auto, auto_experimenter, expected):
    view = build_view(5, status(auto=auto), [], facts(running=2, stage=stage), auto_experimenter)
    assert view.step is Step.RUNNING and view.stage == stage
    assert view.waiting_for == expected


def test_the_open_session_and_the_devices_make_one_view():
    rig = RigStatus(devices=DEVICES, fault="protective stop", timing=LATE, hand_link="lost 0.3 s",
                    ready_wait="the hand is not at A", stop="stopped")
    view = build_view(9, status(rig=rig, preparing=True, messages=["12:00:00 Go"]), [],
                      facts(running=None, stage=None), auto_experimenter=False)
    assert (view.version, view.code, view.seed, view.step) == (9, "M01", 7, Step.PLAN)
    assert view.theta_star == [ThetaStar(after_interaction=3, a=1.0, delta=0.5, k=2.0)]
    assert (view.arm, view.hand, view.gripper) == ("mock arm, 125 Hz", "simulated hand", "no gripper")
    assert view.timing == "real-time priority (SCHED_FIFO)"
    assert view.timing_warning == LATE.describe()
    assert (view.arm_fault, view.hand_link, view.ready_wait, view.stop) == (
        "protective stop", "lost 0.3 s", "the hand is not at A", "stopped")
    assert view.preparing and view.learner == "fitting the next θ"
    assert view.messages == ["12:00:00 Go"] and view.waiting_for is None
    assert view.learning == "the learner's first choice; 45% sure"


def test_without_a_session_the_view_shows_no_rig_and_no_engine():
    view = build_view(1, status(), [], None, auto_experimenter=False)
    assert view.state is None and view.code is None and view.trials == []
    assert (view.arm, view.hand, view.timing, view.stop) == ("no rig open", "", "", "armed")


def test_news_changes_the_status_and_keeps_the_engine_part_of_the_view_shown():
    shown = build_view(3, status(), [], facts(running=2, stage=Stage.PREPARE), False)
    news = with_news(shown, status(rig=RigStatus(devices=DEVICES, stop="stopping"),
                                   messages=["12:00:01 STOP ARM: the arm is stopping"]))
    assert (news.version, news.state, news.waiting_for) == (3, shown.state, Stage.PREPARE)
    assert news.stop == "stopping" and news.arm == "mock arm, 125 Hz"
    assert news.messages == ["12:00:01 STOP ARM: the arm is stopping"]


@pytest.mark.parametrize(("devices", "realtime", "words"), [
    (None, True, ""),
    (DEVICES, False, "simulated time"),
    (DEVICES.model_copy(update={"realtime_priority": False}), True,
     "no real-time priority (normal scheduling): trials may run late on a busy machine"),
])
def test_the_rigs_scheduling_in_words(devices, realtime, words):
    assert timing_words(devices, realtime) == words

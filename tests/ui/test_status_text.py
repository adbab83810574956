"""The dashboard's words for a session state: 1-based counts, what to press, and blinding."""

from __future__ import annotations

from app.protocol.plan import Rating, protocol_slots
from app.protocol.state import SessionState
from app.session.config import LabConfig
from app.session.overview import ParticipantSummary, SessionStatus
from app.session.recording import RecordingStatus
from app.session.runner import END_REASON, RunnerView
from app.ui.status_text import (
    devices_markdown,
    learner_markdown,
    overview_markdown,
    progress_markdown,
    start_blocker,
    status_line,
)
from robot_io.hands.simulated_hand import Scenario
from session_store.models import Trial
from session_store.vocabulary import Phase, ThetaOrigin

CONFIG = LabConfig().study_config(Scenario.PERTURBED, 0)  # the paper's protocol: 5 + 4×5 + 1 + 4×2
SLOTS = protocol_slots(CONFIG)


def view_at(interaction: int, **state) -> RunnerView:
    return RunnerView(code="P07", scenario=Scenario.PERTURBED,
                      state=SessionState(slots=SLOTS, cursor=interaction - 1, **state))


def test_counts_are_one_based_and_name_the_phase():
    assert progress_markdown(view_at(1)).endswith("Initial handovers · handover 1 of 5")
    assert progress_markdown(view_at(13)).endswith("Learning batch 2 of 4 · handover 3 of 5")
    assert progress_markdown(view_at(26)).endswith("Handover with the learned best")
    assert progress_markdown(view_at(27)).endswith("Questionnaire · 0 of 3 answered")
    answered = {"Q1": "4", "Q2": "Yes", "Q3": "5"}
    assert progress_markdown(view_at(29, answers=answered)).endswith(
        "Validation pair 2 of 4 · handover 1 of 2")


def test_status_lines_say_what_to_press():
    assert status_line(view_at(3, paused=True)) == \
        "**Paused** — press **Resume session** to continue."
    assert start_blocker(view_at(3, paused=True)) == "the session is paused: press Resume session"
    stopped = view_at(3).model_copy(update={"stop": "stopped"})
    assert "press **Re-arm**" in status_line(stopped)
    assert "Stopping" in status_line(view_at(3).model_copy(update={"stop": "stopping"}))
    assert status_line(view_at(3, awaiting=Rating.HINT)).startswith(
        "**Waiting for the participant's hint** about handover 3 on the tablet")


def test_blinding_hides_theta_and_origin_of_validation_trials_only():
    def trial(index: int, phase: Phase, origin: ThetaOrigin) -> Trial:
        return Trial(trial_index=index, interaction=index, attempt=1, phase=phase, batch=1,
                     position=1, theta_a=3.21, theta_delta=0.12, theta_k=4.56, origin=origin,
                     hand_seed=1, started_at="2026-01-01T00:00:00+00:00")
    trials = [trial(26, Phase.LEARNING, ThetaOrigin.LEARNED),
              trial(29, Phase.VALIDATION, ThetaOrigin.BEST)]
    view = view_at(30, answers={"Q1": "4"}).model_copy(update={"trials": trials})
    blind, open_ = learner_markdown(view, blind=True), learner_markdown(view, blind=False)
    validation_row = next(line for line in blind.splitlines() if line.startswith("| 29 |"))
    assert "3.21" not in validation_row and "best" not in validation_row
    assert "3.21" in next(line for line in blind.splitlines() if line.startswith("| 26 |"))
    assert "| 29 | 29 | validation | 3.21 |" in open_ and "| best |" in open_


def test_the_overview_says_each_status_in_a_word_or_two():
    def row(status: SessionStatus, detail: str = "") -> ParticipantSummary:
        return ParticipantSummary(code="P01", scenario=Scenario.PERTURBED, completed=3,
                                  interactions=34, status=status, detail=detail)
    cells = [overview_markdown([row(*case)]).splitlines()[2].split(" | ")[3] for case in (
        (SessionStatus.PAUSED, END_REASON), (SessionStatus.PAUSED, "a break"),
        (SessionStatus.OPEN, ""), (SessionStatus.OPEN, "a break"), (SessionStatus.COMPLETE,),
        (SessionStatus.INTERRUPTED,))]
    assert cells == ["ended early", "paused", "open now", "open, paused", "complete", "interrupted"]
    unreadable = overview_markdown([row(SessionStatus.UNREADABLE, "database disk image is malformed")])
    assert "| unreadable |" in unreadable and unreadable.endswith(
        "Unreadable:\n- P01: database disk image is malformed")


def test_the_devices_panel_says_how_settled_the_learner_is_once_it_can():
    """The stopping signal in words (app.protocol.learning_words), under the learner's line; no line
    before the first learning batch has given one."""
    assert "learning" not in devices_markdown(view_at(6))
    settled = view_at(11).model_copy(update={"learning": "the learner's choice has not changed in "
                                                        "1 batch; 92% sure"})
    assert ("- **learning**: the learner's choice has not changed in 1 batch; 92% sure"
            in devices_markdown(settled))


def test_the_devices_panel_shows_the_recording_its_missing_streams_and_a_stall():
    recording = RecordingStatus(kind="labrecorder", path="/s/recordings/sub-P07/ses-01/beh/"
                                "sub-P07_ses-01_task-handover_run-002_beh.xdf", run=2, size=123_456,
                                streams=["handover-markers", "handover-robot", "Mocap"],
                                missing=["EyeTracker"])
    assert "recording" not in devices_markdown(view_at(6))  # no [recording]: no line
    shown = devices_markdown(view_at(6).model_copy(update={"recording": recording}))
    assert ("- **recording** (labrecorder, run 2): recording "
            "`sub-P07_ses-01_task-handover_run-002_beh.xdf`, 123.5 kB") in shown
    assert "streams: handover-markers, handover-robot, Mocap" in shown
    assert "⚠ **not found, not recorded**: EyeTracker" in shown
    stalled = recording.model_copy(update={"warning": "the recording stopped growing: …"})
    assert "123.5 kB — ⚠ **the recording stopped growing: …**" in \
        devices_markdown(view_at(6).model_copy(update={"recording": stalled}))

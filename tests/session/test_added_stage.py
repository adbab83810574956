"""A confirmed stage before Go, added in one place (a row of the cycle's table, here through the table's
extension point ``robot_io.control.stages.extended``), reaches everything that runs or shows the cycle:
the rig process waits in it until the experimenter confirms, the dashboard shows its button and its
words, the session stores its ``trial_stage`` event and the report counts it. After the test it is gone.

The session runs on the mock arm and the simulated hand on simulated time, so the trial's cycle is
the rig's whole cycle; only the experimenter's confirmations are the test's. It takes longer than
20 s on a loaded machine: the learner's process starts, and the report draws its figures."""

from __future__ import annotations

from collections.abc import Iterator

import pandas as pd
import pytest
import viser
from support.engine import SHORT_PROTOCOL
from support.runner import READY_CEILING_S, Probe

from app.analysis.report import build_report
from app.protocol.errors import RefusedAction
from app.protocol.state import Step
from app.session.config import LabConfig
from app.session.runner import SessionRunner
from app.ui.dashboard import gate_buttons
from app.ui.stage_words import stage_words
from app.ui.status_text import cycle_markdown, status_line
from robot_io.control.stages import Confirmation, CycleTable, Part, Stage, StageRow, current, extended
from robot_io.hands.simulated_hand import Scenario
from session_store.read_only_copy import reading
from session_store.store import ParticipantStore

GAZE = StageRow(name="gaze", part=Part.BEFORE_GO, entry="the object is loaded",
                does="waits while the participant looks at the object",
                exit="the experimenter saw the participant look at it",
                says="the participant looks at the object",
                gate=Confirmation(button="Gaze seen", asks="**Wait until the participant looks at "
                                                           "the object**, then press **Gaze seen**."))


@pytest.fixture
def with_gaze() -> Iterator[CycleTable]:
    """The application's cycle with the gaze stage before ``ready``, for this test only."""
    with extended(GAZE, before=Stage.READY) as cycle:
        yield cycle
    assert GAZE.name not in current().names


def confirm_when_waiting(runner: SessionRunner, probe: Probe, stage: str) -> None:
    probe.wait(lambda v: v.waiting_for == stage, what=f"the cycle waiting in {stage}")
    runner.confirm(stage)


def test_a_confirmed_stage_before_go_reaches_the_rig_the_dashboard_the_store_and_the_report(
        tmp_path, with_gaze: CycleTable):
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL})
    runner = SessionRunner(tmp_path / "study", lab, realtime=False)
    probe = Probe(runner)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        runner.open("G01", Scenario.STRAIGHTFORWARD, seed=5)
        probe.wait(lambda v: v.step is Step.READY, READY_CEILING_S, "the first θ")
        assert runner.rig is not None and runner.rig.spec.cycle == with_gaze  # the rig runs it
        runner.start_trial()
        confirm_when_waiting(runner, probe, Stage.PREPARE)  # Object loaded
        view = probe.wait(lambda v: v.waiting_for == GAZE.name, what="the cycle waiting in gaze")

        # the dashboard: its button, enabled only now, and its words
        buttons = gate_buttons(server.gui)
        assert [button.label for button in buttons.values()] == ["Object loaded", "Gaze seen", "Go"]
        assert status_line(view) == GAZE.gate.asks
        assert "**[gaze]**" in cycle_markdown(view)
        assert stage_words(GAZE.name).dashboard == GAZE.says
        with pytest.raises(RefusedAction, match="not waiting in 'ready'"):
            runner.confirm(Stage.READY)  # Go before the gaze is refused

        # the rig waits in it: nothing after gaze was reported before the confirmation
        with reading(runner.study, "G01") as stored:
            assert stages_of(stored, 1)[-1] == GAZE.name
        runner.confirm(GAZE.name)
        confirm_when_waiting(runner, probe, Stage.READY)  # Go
        done = probe.wait(lambda v: v.trials and v.trials[-1].outcome is not None, what="the trial's end")
        assert done.trials[-1].outcome == "completed", done.trials[-1].reason
    finally:
        server.stop()
        runner.close()

    with reading(runner.study, "G01") as stored:
        assert stages_of(stored, 1) == ["prepare", "loaded", "gaze", "ready", "go", "reach", "hold",
                                         "release", "retract", "done"]
    report = build_report(runner.study, tmp_path / "report")
    cycle = pd.read_csv(report.tables["cycle"]).set_index("stage")
    assert list(cycle.index) == list(with_gaze.names)
    assert cycle.loc["gaze", "trials"] == 1 and cycle.loc["gaze", "median_s"] > 0
    assert "<td>gaze</td>" in report.html.read_text()


def stages_of(store: ParticipantStore, trial_index: int) -> list[str]:
    return [e.payload["stage"] for e in store.events()
            if e.kind == "trial_stage" and e.payload["trial_index"] == trial_index]

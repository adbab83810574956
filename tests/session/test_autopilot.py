"""The background worker as the simulated experimenter (headless): it starts the trials through the
runner's public actions, counts those that did not happen, and gives up after MAX_FAILED_TRIALS in a
row, saying why on the view (``run-session`` then exits with that reason)."""

from __future__ import annotations

from support.engine import SHORT_PROTOCOL
from support.runner import READY_CEILING_S, Probe

from app.session.autopilot import MAX_FAILED_TRIALS
from app.session.config import LabConfig
from app.session.runner import SessionRunner
from robot_io.hands.simulated_hand import Scenario


def test_the_simulated_experimenter_gives_up_after_starts_refused_in_a_row(tmp_path):
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL})
    runner = SessionRunner(tmp_path / "study", lab, realtime=False, auto_experimenter=True)
    probe = Probe(runner)
    try:
        runner.stop()  # STOP ARM before the session opens: every Start is refused until Re-arm
        runner.set_auto(True)
        runner.open("M01", Scenario.PERTURBED, seed=1)
        view = probe.wait(lambda v: v.failed is not None, READY_CEILING_S,
                          "the simulated experimenter to give up")
        assert view.failed == f"{MAX_FAILED_TRIALS} trials in a row did not complete; the last: ?"
        assert view.messages[-1].endswith(view.failed)
        refused = [m for m in view.messages if "Start refused: the arm was stopped" in m]
        assert len(refused) == len(view.messages) - 1  # the list keeps the latest only
        assert view.trials == [] and view.stop == "stopped"
    finally:
        runner.close()

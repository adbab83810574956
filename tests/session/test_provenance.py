"""Every placement, answer and validation rating records who made it. A session whose first batch
the person places on the tablet and whose rest the simulated participant rates (the dashboard's
switch, through the runner that both screens use): the export tells every row's origin apart, the
switch is an event, and the report counts only the person's ratings unless told otherwise."""

from __future__ import annotations

import html

import pandas as pd
import pytest
from support.engine import SHORT_PROTOCOL
from support.runner import headless_runner

from app.analysis.report import build_report
from app.protocol.state import Step
from robot_io.hands.simulated_hand import Scenario
from session_store.export import export_study, read_table


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    study = tmp_path_factory.mktemp("study")
    runner, probe = headless_runner(study, SHORT_PROTOCOL)
    # The waits' ceilings are for a hung session (a rig process to start, learner fits on a loaded
    # machine), not measurements.
    try:
        runner.open("H01", Scenario.PERTURBED, seed=4)
        for interaction, position in enumerate((0.2, 0.8, 0.5), 1):  # the person's, from the tablet
            probe.wait(lambda v, i=interaction: v.step is Step.PLACE and v.state.slot.interaction == i,
                       what=f"interaction {interaction}'s placement", timeout=300)
            runner.place(interaction, position=position)
        runner.set_auto(True)  # "Simulated participant rates" switched on
        view = probe.wait(lambda v: v.step is Step.DONE or v.failed is not None,
                          what="the session's end (or its failure)", timeout=600)
        assert view.failed is None and view.state.completed == 9
    finally:
        runner.close()
    return study


def test_the_export_tells_every_rows_origin(study, tmp_path):
    """Slow (~27 s in a loaded full run) as the module's first test: it pays for ``study``, a
    short session run by the headless session runner (its rig process and learner) to its end."""
    export_study(study, tmp_path)
    placements = read_table(tmp_path, "placements").set_index("interaction")["actor"]
    assert placements.to_dict() == {1: "participant", 2: "participant", 3: "participant",
                                    4: "simulated_participant", 5: "simulated_participant",
                                    6: "simulated_participant"}
    for table in ("answers", "validation_ratings"):
        actors = read_table(tmp_path, table)["actor"]
        assert len(actors) > 0 and (actors == "simulated_participant").all(), table
    events = read_table(tmp_path, "events")
    switches = events[events["kind"] == "simulated_participant_switched"]
    assert switches["payload"].tolist() == ['{"on": true}']
    assert switches["actor"].tolist() == ["experimenter"]
    placed = events[events["kind"] == "placement_made"]
    before = placed[placed["seq"] < switches["seq"].iloc[0]]
    assert (before["actor"] == "participant").all() and len(before) == 3
    assert (placed[placed["seq"] > switches["seq"].iloc[0]]["actor"] == "simulated_participant"
            ).all()
    assert not events["actor"].isna().any()


def test_the_report_counts_the_persons_ratings_unless_told_otherwise(study, tmp_path):
    """H01's learning batch was placed by the simulated participant: its θ* is not a person's, so
    the report leaves H01 out of the paper's tables (issue 45) unless told to count it."""
    own = build_report(study, tmp_path / "own")
    assert "marked § and left out of Tables II–IV and the tests: H01" in own.ratings_counted
    assert html.escape(own.ratings_counted) in own.html.read_text()
    assert pd.read_csv(own.tables["table3_perturbed"]).empty
    everything = build_report(study, tmp_path / "all", include_simulated=True)
    assert "by --include-simulated, the simulated participant's" in everything.ratings_counted
    scores = pd.read_csv(everything.tables["table3_perturbed"])
    assert scores["pairs"].tolist() == [1] and scores["simulated_learning"].tolist() == [True]

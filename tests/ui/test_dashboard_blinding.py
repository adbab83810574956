"""The validation is blind unless asked otherwise: ``handover serve`` without options hides the θ and
the origin (θ* or Sobol) of validation trials in the dashboard's Learner panel, ``--unblind`` shows
them, and each session records the blinding of every dashboard that served it (the restart with
``--unblind`` too), so the report can say how its validation was run.

A participant's whole session (short protocol, one validation pair) is stored first by the session
engine and its simulated participant; then `handover serve` opens it twice, blind and unblinded, and
headless Chromium reads the Learner panel.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import Page
from support.browser import chromium, open_folder, open_page, serve, shot, unlock_dashboard
from support.engine import drive_until, short_config
from support.waiting import wait_for

from app.analysis.report import build_report
from app.protocol.engine import SessionEngine
from app.protocol.state import Step
from robot_io.hands.simulated_hand import Scenario
from session_store.store import ParticipantStore

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: The cells of the Learner panel's rows of validation trials (trial, handover, phase, a, δ, k,
#: origin, outcome).
VALIDATION_ROWS_JS = """() => [...document.querySelectorAll('tr')]
    .map(row => [...row.cells].map(cell => cell.innerText.trim()))
    .filter(cells => cells[2] === 'validation')"""


def validation_rows(dashboard: Page) -> list[list[str]]:
    """The Learner panel's validation rows, once both trials of the pair are listed."""
    return wait_for(lambda: (rows := dashboard.evaluate(VALIDATION_ROWS_JS)) and len(rows) == 2
                    and rows, "the Learner panel's two validation trials",
                    seen=lambda: dashboard.inner_text("body")[-1500:])


def learner_panel(served, shots: Path, name: str) -> tuple[list[list[str]], str]:
    """The validation rows and the text of the Learner panel of ``served``'s dashboard (a
    screenshot of it in ``shots``)."""
    with chromium() as browser:
        dashboard = open_page(browser, served.dashboard_url, size=(1400, 900))
        unlock_dashboard(dashboard)
        open_folder(dashboard, "Learner")
        rows = validation_rows(dashboard)
        dashboard.get_by_text("θ* history").scroll_into_view_if_needed()
        shot(dashboard, shots, name)
        return rows, dashboard.inner_text("body")


def test_serve_hides_validation_theta_and_origin_unless_unblind_and_records_both(tmp_path):
    """Slow: a whole short session with the real learner first (the validation trials whose θ is
    hidden), then two ``serve`` processes on it, each with Chromium, blind and not."""
    study = tmp_path / "study"
    engine = SessionEngine.create(study, "B01", short_config(seed=4, scenario=Scenario.PERTURBED))
    drive_until(engine, Step.DONE)
    engine.close()

    with serve(tmp_path, "--participant", "B01", log_name="blind.log") as served:
        blind, blind_text = learner_panel(served, tmp_path / "shots", "learner-blind")
        served.shutdown()
    assert all(row[3:7] == ["hidden"] * 4 for row in blind), blind
    assert "Double-blind: θ and origin of validation trials are hidden." in blind_text

    with serve(tmp_path, "--participant", "B01", "--unblind", log_name="unblind.log") as served:
        shown, shown_text = learner_panel(served, tmp_path / "shots", "learner-unblind")
        printed = served.shutdown()
    assert ("validation:               NOT blind (--unblind): the dashboard shows which trial is "
            "θ*") in printed
    assert sorted(row[6] for row in shown) == ["best", "sobol"], shown
    assert all(value != "hidden" for row in shown for value in row[3:7]), shown
    assert "Not blind (serve --unblind)" in shown_text

    store = ParticipantStore.open(study, "B01")
    try:
        recorded = [(e.actor.value, e.payload) for e in store.events()
                    if e.kind == "validation_blinding_set"]
    finally:
        store.close()
    assert recorded == [("experimenter", {"blind": True}), ("experimenter", {"blind": False})]
    # its validation trials ran before either dashboard served it: the report says so
    report = build_report(study, tmp_path / "report")
    sessions = (tmp_path / "report" / "tables" / "sessions.csv").read_text()
    assert "not recorded for 2 of 2 validation trials" in sessions, sessions
    assert report.not_blind == {}

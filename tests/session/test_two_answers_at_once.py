"""Issue 45, item 4: two answers for the same prompt at once — the participant's on the tablet and
the experimenter's on the dashboard (Enter for the participant). The rule (docs/protocol.md, "Two
answers at once"): the answer stored first counts; the other is not dropped without a word but
stored as an ``entry_not_used`` event (who, what it said, what counted instead), and the
experimenter sees it — the status line until the next trial starts, Recent events, and the refusal
under the controls when it was theirs. A second tap by the same person is a double tap: refused,
nothing recorded.

A coactive session of the short protocol through the runner both screens use (trials started by the
simulated experimenter, on simulated time); the hints about handover 1 arrive from both sides, the
experimenter's first; the placement of handover 2 arrives from both sides, the participant's first."""

from __future__ import annotations

import html
import re

import pytest
from support.engine import SHORT_PROTOCOL
from support.runner import headless_runner

from app.analysis.report import build_report
from app.protocol.entries import EntryNotUsed
from app.protocol.errors import RefusedAction
from app.protocol.state import Step
from app.ui.status_text import status_line
from robot_io.hands.simulated_hand import Scenario
from session_store.read_only_copy import reading
from session_store.vocabulary import Hint, Rater

HINT_NOT_USED = ("Not used: the participant's hint about handover 1 (sooner) came after the "
                 "experimenter's (later), which counts")
PLACEMENT_NOT_USED = ("Not used: the experimenter's placement of handover 2 (at 0.90) came after "
                      "the participant's (at 0.20), which counts")


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    study = tmp_path_factory.mktemp("study")
    runner, probe = headless_runner(study, {**SHORT_PROTOCOL, "coactive": True})
    try:
        runner.open("T01", Scenario.PERTURBED, seed=3)
        probe.wait(lambda v: v.step is Step.PLACE, timeout=300, what="handover 1's placement")
        runner.place(1, position=0.5)
        probe.wait(lambda v: v.step is Step.HINT, what="the hint about handover 1")
        runner.hint(1, Hint.LATER, by=Rater.EXPERIMENTER)  # the dashboard's, stored first
        with pytest.raises(EntryNotUsed, match=re.escape(HINT_NOT_USED)):
            runner.hint(1, Hint.SOONER)  # the tablet's, a moment later
        with pytest.raises(RefusedAction) as double:
            runner.hint(1, Hint.MORE, by=Rater.EXPERIMENTER)  # the experimenter taps again
        assert not isinstance(double.value, EntryNotUsed)
        probe.wait(lambda v: v.step is Step.PLACE and v.state.slot.interaction == 2, timeout=300,
                   what="handover 2's placement")
        runner.place(2, position=0.2)  # the tablet's, stored first
        with pytest.raises(EntryNotUsed, match=re.escape(PLACEMENT_NOT_USED)):
            runner.place(2, position=0.9, by=Rater.EXPERIMENTER)
        runner.hint(2, None)
        probe.wait(lambda v: v.step is Step.RUNNING and v.state.slot.interaction == 3,
                   timeout=300, what="the next trial")
        views = list(probe.views)
    finally:
        runner.close()
    report = build_report(study, tmp_path_factory.mktemp("report"))
    with reading(study, "T01") as store:
        return store.events(), store.rows("hints"), views, report.html.read_text()


def test_both_answers_are_recorded_and_the_first_counts(session):
    """Slow: the module's ``session`` fixture runs here, a runner on simulated time with its rig
    process and learner up to handover 3, then the study's report with its figures."""
    events, hints, *_ = session
    assert [(h.interaction, h.hint, h.actor) for h in hints] == [
        (1, Hint.LATER, Rater.EXPERIMENTER), (2, None, Rater.PARTICIPANT)]
    not_used = [e for e in events if e.kind == "entry_not_used"]
    assert [(e.actor, e.payload["entry"], e.payload["interaction"], e.payload["value"],
             e.payload["counted_actor"], e.payload["counted_value"]) for e in not_used] == [
        ("participant", "hint", 1, "sooner", "experimenter", "later"),
        ("experimenter", "placement", 2, "at 0.90", "participant", "at 0.20")]
    counted = {e.seq: e for e in events}
    assert counted[not_used[0].payload["counted_seq"]].kind == "hint_given"
    assert counted[not_used[1].payload["counted_seq"]].kind == "placement_made"


def test_the_experimenter_sees_what_was_not_used_until_the_next_trial(session):
    _, _, views, _ = session
    for words in (HINT_NOT_USED, PLACEMENT_NOT_USED):
        shown = [v for v in views if v.state is not None and v.state.not_used is not None
                 and words in status_line(v)]
        assert shown, f"no view showed {words!r}"
        assert status_line(shown[0]).startswith(f"⚠ **{words}.** · ")
        assert any(m.endswith(f"⚠ {words}") for m in shown[-1].messages), shown[-1].messages
        # from the next trial's start on, the status line is about that trial
        later = views[views.index(shown[-1]) + 1:]
        assert any(v.step is Step.RUNNING for v in later)
        assert all("Not used" not in status_line(v) for v in later if v.step is Step.RUNNING)


def test_the_report_lists_each_answer_not_used(session):
    page = html.unescape(session[-1])
    assert f"T01: {HINT_NOT_USED}" in page and f"T01: {PLACEMENT_NOT_USED}" in page

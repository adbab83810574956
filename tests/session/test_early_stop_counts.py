"""Issue 45, item 2: learning that stops early (``[protocol] stop_when_settled``) shortens the plan,
and every count the experimenter reads follows the plan as it now is — the Session panel, the status
line at the end, the Study table — and the stop itself is news: in the status line until the next
trial, in Recent events, and in the Session panel for the rest of the session.

One headless session through the runner both screens use, with the simulated participant: the short
protocol with 4 learning batches stops after the first (:data:`STOPPING_PROTOCOL`), so the plan of 18
becomes 9. It takes about 30 s: 9 trials on simulated time and 3 learner fits.
"""

from __future__ import annotations

import pytest
from support.engine import STOPPING_PROTOCOL
from support.runner import headless_runner

from app.protocol.state import Step
from app.session.runner import RunnerView
from app.ui.status_text import overview_markdown, progress_markdown, status_line
from robot_io.hands.simulated_hand import Scenario

HEADLINE = "Learning stopped early after batch 1 of 4: the learner is sure enough of the best " \
           "handover, 9 handovers fewer"


@pytest.fixture(scope="module")
def session(tmp_path_factory) -> tuple[list[RunnerView], RunnerView, RunnerView]:
    """Every view published, the last one of the open session, and the view after End session."""
    study = tmp_path_factory.mktemp("study")
    runner, probe = headless_runner(study, STOPPING_PROTOCOL)
    try:
        runner.set_auto(True)
        runner.open("E01", Scenario.STRAIGHTFORWARD, seed=1)
        done = probe.wait(lambda v: v.step is Step.DONE or v.failed is not None, timeout=600,
                          what="the session's end (or its failure)")
        assert done.failed is None, done.failed
        runner.end_session()
        return list(probe.views), done, runner.view
    finally:
        runner.close()


def test_the_counts_follow_the_plan_after_the_stop(session):
    _, done, ended = session
    assert done.state.stopped_after == 6, "the simulated participant settles after batch 1"
    assert progress_markdown(done).splitlines()[0] == \
        "**E01** · straightforward · 9 of 9 handovers completed  "
    assert status_line(done).startswith("**Session complete**")
    (line,) = done.overview
    assert (line.completed, line.interactions) == (9, 9)
    assert "| E01 | straightforward | 9 of 9 | open now |" in overview_markdown(done.overview)
    assert "| E01 | straightforward | 9 of 9 | complete |" in overview_markdown(ended.overview)


def test_the_stop_is_news_where_the_experimenter_looks(session):
    views, done, _ = session
    ready = next(v for v in views if v.step is Step.READY and v.state.stopped_after is not None)
    assert status_line(ready).startswith(f"**{HEADLINE}.** · **Ready")
    assert any(m.endswith(f"{HEADLINE}: after learning batch 1 of 4 the learner was "
                          f"{m.split('the learner was ')[1]}") for m in ready.messages
               if "the learner was " in m), ready.messages
    assert "6 of 9 handovers completed" in progress_markdown(ready)
    assert "| E01 | straightforward | 6 of 9 | open now |" in overview_markdown(ready.overview)
    assert HEADLINE in progress_markdown(done)  # the Session panel keeps it
    assert not status_line(done).startswith("**Learning")  # the status line moved on
    assert done.learning.startswith(f"{HEADLINE} (after learning batch 1 of 4 the learner was ")

"""``handover serve`` killed mid-session with the simulated participant rating (issue 12): SIGKILL,
restart, reopen the participant, run to the end — nothing lost, nothing repeated.

One session with every phase of the protocol, twice over where the paper has more (3 initial
interactions, 2 learning batches of 3, the best, 2 validation pairs: 14 interactions; the paper's 34
run end to end through ``run-session`` in tests/protocol/test_resume_exact.py, uninterrupted
and killed) on the mock arm, on the wall clock, with the
experimenter's part done on the dashboard in headless Chromium (Start trial; with the simulated
participant rating, Object loaded and Go are given by themselves). The serve process — the Python
interpreter itself, which holds the participant's writer lock — is killed three times, at moments
chosen by polling the database read-only: while a trial is under way, while a placement is due, and
while a validation rating is due. Each time serve is started again on the same study and the
participant reopened as the experimenter would: twice with the dashboard's "Create or resume", once
with ``--participant``. At the end the completed interactions are 1–14 once each, the trial that
was running is recorded as interrupted and repeated with its θ, and the placements, comparisons,
answers, ratings and θ are those of the session's uninterrupted twin (tests/support/twin.py); the
event log replays, through the protocol, to what the dashboard showed live and to the tables.
"""

from __future__ import annotations

import signal
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import pytest
from playwright.sync_api import Browser, Page
from support.browser import (
    Served,
    chromium,
    keep_starting,
    open_page,
    open_participant,
    serve,
    unlock_dashboard,
    wait_text,
)
from support.processes import descendants, still_alive
from support.store import Progress, assert_same_outcome, progress, session_outcome
from support.twin import uninterrupted_twin

from app.protocol.doctor import examine
from app.protocol.state import Step
from app.protocol.stored_session import stored_session
from session_store.lock import holder_of
from session_store.models import TrialOutcome
from session_store.read_only_copy import reading
from session_store.store import participant_path
from session_store.vocabulary import QUESTIONS, Phase

pytestmark = [pytest.mark.browser, pytest.mark.slow]

CODE, SEED = "P01", 11
#: Every phase, two learning batches and two validation pairs (the [protocol] table).
PROTOCOL = ("initial_trials = 3\nbatch_size = 3\nlearning_batches = 2\nbest_trials = 1\n"
            "validation_batches = 2\n")
INTERACTIONS = 14
#: The first validation interaction (after 3 initial, 2 × 3 learning and 1 best).
FIRST_VALIDATION = 11
#: How long the rig and learner processes of a killed serve may take to see it gone [s].
ORPHANS_END_S = 30.0



class Kill(NamedTuple):
    """A moment to kill serve at, as the database shows it (polled read-only, every few tens of
    ms), and the step the session must then be reopened at."""

    resumes_at: str
    when: Callable[[Progress], bool]


KILLS = (
    # a trial under way (the robot reaching out or holding the object out; seconds each)
    Kill("running", lambda p: p.completed >= 3 and p.kind == "trial_stage"
         and p.payload["stage"] in ("reach", "hold")),
    # a learning trial stored, its placement due (the simulated participant places AUTO_DELAY_S =
    # 0.6 s later)
    Kill("place", lambda p: p.completed >= 8 and p.kind == "trial_ended"
         and p.payload["outcome"] == "completed"),
    # the second trial of a validation pair stored, its rating due (as long again)
    Kill("rate", lambda p: p.completed > FIRST_VALIDATION
         and (p.completed - FIRST_VALIDATION) % 2 == 1 and p.kind == "trial_ended"
         and p.payload["outcome"] == "completed"),
)
#: How the participant is reopened after each kill, as an experimenter would: the dashboard's
#: "Create or resume", or serve's --participant.
REOPEN = ("dashboard", "command line", "dashboard")


def dashboard_of(browser: Browser, served: Served) -> Page:
    page = open_page(browser, served.dashboard_url, size=(1400, 900))
    unlock_dashboard(page)
    return page


def holds_the_lock(served: Served, database: Path) -> None:
    """The serve process itself (no wrapper) is the participant's writer."""
    holder = holder_of(database)
    assert holder is not None and holder.pid == served.process.pid, holder


def kill_writer(served: Served, database: Path) -> None:
    """SIGKILL serve; its lock is free at once, and its rig and learner end by themselves."""
    children = descendants(served.process.pid)
    assert children, "serve runs its rig (and learner) in processes of their own"
    served.process.send_signal(signal.SIGKILL)
    served.process.wait()
    assert holder_of(database) is None
    assert still_alive(children, ORPHANS_END_S) == []


def run_until(dashboard: Page, database: Path, moment: Callable[[Progress], bool]) -> None:
    """Start trials until the database shows ``moment``."""
    keep_starting(dashboard, lambda: True if moment(progress(database)) else None)


def run_to_the_end(dashboard: Page) -> None:
    """Start trials until the dashboard says the session is complete, with every interaction."""
    keep_starting(dashboard, lambda: "Session complete" in dashboard.inner_text("body") or None)
    wait_text(dashboard, f"{INTERACTIONS} of {INTERACTIONS} handovers completed")


def test_serve_killed_mid_session_resumes_and_loses_or_repeats_nothing(tmp_path: Path) -> None:
    """The suite's longest test (65 s alone, 115 s in a fresh clone's run): 14 interactions on the
    wall clock through four ``serve`` processes (each starting its rig process and its learner, torch
    included) and Chromium, then the uninterrupted twin's 14 interactions and their learner. The
    straightforward scenario: its handovers take half as long as the perturbed one's, and what this
    test checks does not depend on them."""
    database = participant_path(tmp_path / "study", CODE)
    with chromium() as browser:
        for run, (opened, kill) in enumerate(zip(("created", *REOPEN), (*KILLS, None),
                                                 strict=True)):
            arguments = {"created": ("--participant", CODE, "--scenario", "straightforward", "--seed",
                                     str(SEED)),
                         "command line": ("--participant", CODE), "dashboard": ()}[opened]
            with serve(tmp_path, "--auto-participant", *arguments, protocol_toml=PROTOCOL,
                       log_name=f"serve-{run}.log") as served:
                dashboard = dashboard_of(browser, served)
                if opened == "dashboard":
                    open_participant(dashboard, CODE)  # "Create or resume"
                holds_the_lock(served, database)
                if kill is not None:
                    run_until(dashboard, database, kill.when)
                    kill_writer(served, database)
                else:
                    run_to_the_end(dashboard)
                    output = served.shutdown()
                    assert served.process.returncode == 0 and "closed" in output, output[-2000:]
                dashboard.context.close()

    with reading(database.parent, CODE) as store:
        _, events, state = stored_session(store)
        trials = store.rows("trials", order_by="trial_index")
        answers = {a.question: a.value for a in store.rows("answers")}
    resumed = [e.payload["step"] for e in events if e.kind == "session_resumed"]
    assert resumed == [kill.resumes_at for kill in KILLS]  # each kill landed where aimed

    # Nothing lost, nothing repeated: every interaction completed once, in order; the one trial
    # the kill interrupted is recorded so and repeated (same interaction, same θ), never rated.
    completed = [t for t in trials if t.outcome is TrialOutcome.COMPLETED]
    assert [t.interaction for t in completed] == list(range(1, INTERACTIONS + 1))
    [interrupted] = [t for t in trials if t.outcome is not TrialOutcome.COMPLETED]
    assert interrupted.reason == "session interrupted"
    redo = completed[interrupted.interaction - 1]
    assert (redo.attempt, redo.theta_a, redo.theta_delta, redo.theta_k) == (
        2, interrupted.theta_a, interrupted.theta_delta, interrupted.theta_k)
    outcome = session_outcome(database)
    assert [row[0] for row in outcome["placements"]] == \
        [t.interaction for t in completed if t.phase in (Phase.INITIAL, Phase.LEARNING)]
    assert [row[0] for row in outcome["validation"]] == \
        list(range(FIRST_VALIDATION + 1, INTERACTIONS + 1, 2))
    assert [row[0] for row in outcome["answers"]] == [q.id for q in QUESTIONS]

    # The same placements, comparisons, answers, ratings and θ as the uninterrupted twin.
    assert_same_outcome(database, uninterrupted_twin(database, tmp_path / "twin"))

    # The event log replays through the protocol to what the dashboard showed live (the session
    # complete, every interaction completed), and to the tables written beside it.
    verdict = examine(database)
    assert verdict.ok, verdict.text()
    assert state.step is Step.DONE and state.completed == INTERACTIONS
    assert state.completed_trial == {t.interaction: t.trial_index for t in completed}
    assert state.answers == answers
    placed = [(e.payload["interaction"], e.payload["position"], e.payload["equal_to"])
              for e in events if e.kind == "placement_made"]
    assert placed == outcome["placements"]
    compared = sorted((e.payload["interaction"], *pair) for e in events
                      if e.kind == "placement_made" for pair in e.payload["comparisons"])
    assert compared == outcome["comparisons"]
    rated = [(e.payload["interaction"], e.payload["rating"]) for e in events
             if e.kind == "validation_rated"]
    assert rated == outcome["validation"]

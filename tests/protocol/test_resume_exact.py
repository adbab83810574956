"""Resuming is exact: in one process a restored learner suggests bit for bit what the stored one
would have, and a session killed with SIGKILL at random moments and resumed each time ends with the
same placements, comparisons, answers, ratings and completed trials as one that was never
interrupted (θ equal up to the last bits that floating point leaves to each process)."""

from __future__ import annotations

import multiprocessing as mp
import os
import random
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support.engine import SESSION_LOOP_TOML, drive_until, new_engine
from support.store import assert_same_outcome, event_count, session_outcome
from support.waiting import CEILING_S, tail, wait_for

from app.learning.config import LearnerConfig
from app.learning.learner import PreferenceLearner
from app.learning.models import Comparison, Interaction, ParameterBox
from app.learning.worker import LearnerClient
from app.protocol.engine import SessionEngine
from app.protocol.state import Step
from session_store.store import ParticipantStore


def test_a_restored_learner_is_the_stored_learner():
    """Through fits, and through interactions that add no comparison (the first of a batch), the
    restored learner's posterior and next θ equal the original's exactly."""
    config = LearnerConfig(box=ParameterBox.unit_cube(3), seed=4)
    target = np.random.default_rng(0).random(3)
    learner, seen = PreferenceLearner(config), []
    for n in range(1, 13):
        theta = learner.suggest().theta
        utility = -np.linalg.norm(np.array(list(theta.values())) - target)
        iid = str(n)
        batch = [] if n % 4 == 1 else seen[-3:]  # every 4th interaction opens a batch: no comparison
        comparisons = [Comparison(winner=iid, loser=j) if utility > u else
                       Comparison(winner=j, loser=iid) for j, u in batch]
        restored = PreferenceLearner.restore(learner.snapshot())
        for one in (learner, restored):
            one.observe(Interaction(interaction_id=iid, theta=theta), comparisons)
        assert restored.model.hyperparameters == learner.model.hyperparameters
        if learner.model.model is not None:
            X, _ = learner.data.tensors()
            assert bool((learner.model.model.posterior(X).mean ==
                         restored.model.model.posterior(X).mean).all())
        assert restored.suggest().theta == learner.suggest().theta
        seen.append((iid, utility))


#: SIGKILLs of the run-session process itself (its own PID: Popen runs the interpreter, no shell).
KILLS = 20


def wait_inside_session(process: subprocess.Popen, database: Path, before: int) -> None:
    """Wait until ``process`` has written an event past the ``before`` there were (it created or
    resumed the session), or has ended."""
    wait_for(lambda: event_count(database) > before or process.poll() is not None,
             f"pid {process.pid} to write its first event (or end)",
             seen=lambda: f"{event_count(database)} events, exit code {process.poll()}")


@pytest.mark.slow
@pytest.mark.soak
def test_sigkill_at_random_moments_then_resume_loses_and_repeats_nothing(tmp_path):
    """Slow (about 100 s): 21 ``run-session`` processes (20 killed at random moments, each resumed),
    each starting its learner, beside the uninterrupted session, all on the wall clock."""
    lab = tmp_path / "lab.toml"
    lab.write_text(SESSION_LOOP_TOML)
    command = [sys.executable, "-m", "app.cli", "run-session", "--participant", "K1", "--scenario",
               "perturbed", "--auto", "--seed", "11", "--no-progress", "--config", str(lab)]
    # The uninterrupted session runs beside the killed ones (another study folder, another writer).
    whole_log = tmp_path / "whole.log"
    with whole_log.open("w") as out:
        whole = subprocess.Popen([*command, "--study", str(tmp_path / "whole")],
                                 stdout=subprocess.DEVNULL, stderr=out)
    try:
        database = tmp_path / "killed" / "K1.sqlite"
        rng, kills = random.Random(2026), 0
        log = tmp_path / "run.log"
        while True:
            before = event_count(database)
            with log.open("w") as err:  # a file, not a pipe nobody reads while the session runs
                process = subprocess.Popen([*command, "--study", str(tmp_path / "killed"), "--resume"],
                                           stdout=subprocess.DEVNULL, stderr=err)
            if kills < KILLS:
                # Kill inside the session, whatever the machine's load: once this run has written an
                # event (created or resumed the session) ...
                wait_inside_session(process, database, before)
                try:
                    # ... then at a random moment of its trials, learner updates and writes: this wait
                    # is the kill's random moment (any moment is valid), not a wait for a state.
                    process.wait(timeout=rng.uniform(0.0, 2.5))
                except subprocess.TimeoutExpired:
                    process.send_signal(signal.SIGKILL)  # the writer itself: Popen runs no shell
                    process.wait()
                    kills += 1
                    continue
            # A ceiling for a hung session, not a measurement.
            code = process.wait(timeout=CEILING_S * 15)
            assert code == 0, tail(log.read_text())
            break
        assert kills == KILLS
        # A ceiling for a hung session, not a measurement.
        assert whole.wait(timeout=CEILING_S * 15) == 0, tail(whole_log.read_text())
    finally:  # a failure above: end the uninterrupted writer too, by its own pid
        if whole.poll() is None:
            whole.kill()
            whole.wait()
    assert_same_outcome(database, tmp_path / "whole" / "K1.sqlite")
    assert len(session_outcome(database)["completed trials"]) == 34
    with sqlite3.connect(database) as conn:
        resumes = conn.execute("SELECT count(*) FROM events WHERE kind = 'session_resumed'"
                               ).fetchone()[0]
    assert resumes == kills  # every kill landed inside a session, every run after it resumed


def _place_and_die_mid_write(study) -> None:  # runs in a forked child
    engine = SessionEngine(ParticipantStore.open(study, "S01"), LearnerClient.for_session)
    add = engine.store.add

    def add_then_die(row) -> None:
        add(row)  # the placement row is written, inside the open transaction...
        os.kill(os.getpid(), signal.SIGKILL)  # ...and the process dies before the commit

    engine.store.add = add_then_die
    engine.place(position=0.9)


@pytest.mark.soak
def test_a_kill_in_the_middle_of_a_write_leaves_the_database_as_before(tmp_path):
    engine = new_engine(tmp_path)
    drive_until(engine, Step.PLACE)
    engine.place(position=0.5)
    drive_until(engine, Step.PLACE)  # the second interaction: its placement makes a comparison
    before = engine.store.counts()
    engine.close()
    child = mp.get_context("fork").Process(target=_place_and_die_mid_write, args=(tmp_path,))
    child.start()
    # exitcode is None until the child has been reaped: wait for its end, never read it early.
    wait_for(lambda: child.exitcode is not None, "the child to die mid-write and be reaped",
             seen=lambda: f"pid {child.pid}, alive {child.is_alive()}")
    assert child.exitcode == -signal.SIGKILL
    resumed = SessionEngine.resume(tmp_path, "S01")
    try:
        after = resumed.store.counts()
        assert after == {**before, "events": before["events"] + 1}  # only session_resumed
        assert resumed.state.step is Step.PLACE
        assert [(c.winner, c.loser) for c in resumed.place(position=0.9)] == [(2, 1)]
    finally:
        resumed.close()

"""Resuming is exact: a restored learner suggests bit-for-bit what the stored one would have, and a
session killed with SIGKILL at random moments and resumed each time ends exactly like one that was
never interrupted."""

from __future__ import annotations

import random
import signal
import sqlite3
import subprocess
import sys

import numpy as np
import pytest

from app.learning.config import LearnerConfig
from app.learning.learner import PreferenceLearner
from app.learning.models import Comparison, Interaction, ParameterBox


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


def _outcome(path) -> dict[str, list]:
    with sqlite3.connect(path) as conn:
        def rows(sql: str) -> list:
            return conn.execute(sql).fetchall()
        return {
            "completed trials": rows("SELECT interaction, theta_a, theta_delta, theta_k FROM trials "
                                     "WHERE outcome = 'completed' ORDER BY interaction"),
            "placements": rows("SELECT interaction, position, equal_to FROM placements "
                               "ORDER BY interaction"),
            "comparisons": rows("SELECT source, winner, loser FROM comparisons "
                                "ORDER BY source, winner, loser"),
            "answers": rows("SELECT question, value FROM answers ORDER BY question"),
            "validation": rows("SELECT interaction, rating FROM validation_ratings "
                               "ORDER BY interaction"),
        }


@pytest.mark.slow
def test_sigkill_at_random_moments_then_resume_loses_and_repeats_nothing(tmp_path):
    command = [sys.executable, "-m", "app.cli", "run-session", "--participant", "K1", "--scenario",
               "perturbed", "--auto", "--seed", "11", "--no-progress"]
    subprocess.run([*command, "--study", str(tmp_path / "whole")], check=True,
                   capture_output=True, timeout=300)
    rng, kills, resume = random.Random(2026), 0, []
    for _ in range(60):
        process = subprocess.Popen([*command, "--study", str(tmp_path / "killed"), *resume],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        resume = ["--resume"]
        try:  # the first 12 runs are killed after 1.5–5 s (spawn, trials, fits, writes), then done
            process.wait(timeout=rng.uniform(1.5, 5.0) if kills < 12 else 300)
        except subprocess.TimeoutExpired:
            process.send_signal(signal.SIGKILL)
            process.wait()
            kills += 1
            continue
        assert process.returncode == 0, process.stderr.read().decode()[-2000:]
        break
    assert kills >= 10
    whole, killed = _outcome(tmp_path / "whole" / "K1.sqlite"), _outcome(tmp_path / "killed" / "K1.sqlite")
    for table in whole:
        assert killed[table] == whole[table], table
    assert len(whole["completed trials"]) == 34
    with sqlite3.connect(tmp_path / "killed" / "K1.sqlite") as conn:
        resumes = conn.execute("SELECT count(*) FROM events WHERE kind = 'session_resumed'").fetchone()
    assert resumes[0] == kills

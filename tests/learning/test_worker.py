"""The learner in a real worker process: pending, timeout fallback, crash restart, shutdown."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest

from app.learning.config import LearnerConfig
from app.learning.learner import PreferenceLearner
from app.learning.models import Comparison, Interaction, ParameterBox, SlotKind
from app.learning.planner import BatchSchedule
from app.learning.worker import LearnerClient

from .conftest import TABLE_I


@pytest.fixture(scope="module")
def client():
    config = LearnerConfig(box=ParameterBox.from_bounds(TABLE_I),
                           schedule=BatchSchedule(n_initial=3, q=3, n_unique=8), seed=11)
    with LearnerClient(config) as handle:
        yield handle
        last = handle.pid
    # ended and released at close (its pipes and process handle too: tests/session/test_open_files)
    assert handle.pid is None and last is not None and not Path(f"/proc/{last}").exists()


def wait_until_answered(client: LearnerClient, limit: float = 60.0):
    deadline = time.monotonic() + limit
    while client.pending:
        assert time.monotonic() < deadline, "the worker never answered"
        time.sleep(0.05)


def test_pending_then_timeout_gives_a_flagged_fallback_in_the_box(client):
    client.submit()
    # the freshly spawned worker is still importing torch: the request is pending
    assert client.pending
    assert client.poll() is None
    fallback = client.get(timeout=0.0)
    assert fallback.fallback
    assert fallback.slot.kind is SlotKind.INITIAL and fallback.slot.index == 0
    client.config.box.to_unit(fallback.theta)  # inside the box
    assert not client.pending  # the fallback answered the request; its late reply is dropped


def test_real_suggestions_follow_and_theta_star_is_reported(client):
    box = client.config.box
    for i in range(1, 4):
        theta = box.from_unit([0.2 * i, 0.5, 0.5])  # what the caller actually ran
        client.submit([Interaction(interaction_id=str(i), theta=theta)],
                      [Comparison(winner=str(i), loser=str(i - 1))] if i > 1 else [])
        wait_until_answered(client)
        suggestion = client.poll()
        assert suggestion is not None and not suggestion.fallback
    assert suggestion.slot.kind is SlotKind.BEST
    # the batch-opening θ* is a handover already felt; the recommended θ* may lie between them
    assert suggestion.theta == client.incumbent
    assert client.incumbent in [box.from_unit([0.2 * i, 0.5, 0.5]) for i in range(1, 4)]
    assert client.best is not None
    state = client.state  # the worker's own snapshot as of its latest reply
    assert [i.interaction_id for i in state.interactions] == ["1", "2", "3"]
    assert state.hyperparameters is not None
    assert PreferenceLearner.restore(state).best().theta == client.best.theta


def test_a_killed_worker_is_detected_and_restarted_with_its_history(client):
    best, shown = client.best, client.incumbent  # the caller runs the batch-opening θ*
    os.kill(client.pid, signal.SIGKILL)
    client.submit([Interaction(interaction_id="4", theta=shown)])
    suggestion = client.get(timeout=120.0)
    assert not suggestion.fallback
    assert suggestion.worker_restarts == client.restarts == 1
    assert suggestion.slot.index == 4 and suggestion.slot.kind is SlotKind.QUERY
    assert client.incumbent == shown  # the replayed history gives the same θ*: the incumbent
    # exactly, the box's posterior-mean maximiser up to the optimiser's tolerance (the replay
    # refits once where the worker refitted step by step: hyperparameters agree to ~1e-9)
    box = client.config.box
    assert box.to_unit(client.best.theta) == pytest.approx(box.to_unit(best.theta), abs=1e-5)

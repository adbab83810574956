"""Shared helpers: a learner on Table I's box driven by a simulated participant."""

from __future__ import annotations

import math

import pytest

from app.learning.config import AcquisitionName, LearnerConfig
from app.learning.learner import PreferenceLearner
from app.learning.models import Interaction, ParameterBox, Placement
from app.learning.planner import BatchSchedule
from app.learning.scale import comparisons_for_newest

TABLE_I = {"a": (1.0, 10.0), "delta": (-1.0, 1.0), "k": (0.01, 15.0)}
TARGET = {"a": 6.0, "delta": -0.3, "k": 9.0}


def utility(box: ParameterBox, theta: dict[str, float]) -> float:
    """Negative unit-cube distance to TARGET: the participant prefers points near it."""
    a, b = box.to_unit(theta), box.to_unit(TARGET)
    return -math.dist(a, b)


def drive(learner: PreferenceLearner, n: int) -> list[dict[str, float]]:
    """Run ``n`` interactions of the learner's schedule with a noiseless participant."""
    shown, placements = [], []
    box = learner.config.box
    for _ in range(n):
        suggestion = learner.suggest()
        if suggestion.slot.position == 1:
            placements = []
        iid = str(suggestion.slot.index + 1)
        u = utility(box, suggestion.theta)
        placements.append(Placement(interaction_id=iid, position=0.5 + math.atan(u) / math.pi))
        learner.observe(Interaction(interaction_id=iid, theta=suggestion.theta),
                        comparisons_for_newest(placements))
        shown.append(suggestion.theta)
    return shown


@pytest.fixture(scope="session")
def client():
    """A one-worker local Dask cluster, shared by the tests that run studies."""
    from app.learning.cluster import dask_client

    with dask_client(workers=1) as dask:
        yield dask


@pytest.fixture(scope="session")
def on_the_cluster(client) -> list[str]:
    """The study commands' ``--scheduler`` option naming the shared cluster's scheduler: they reach
    it as they reach a lab's, instead of starting a LocalCluster of their own for each run (a
    worker process that imports torch, ~4 CPU-seconds). Their default, a LocalCluster of
    ``--workers`` processes, is tested in test_study.py::test_two_dask_workers_write_the_same_csv_as_one."""
    return ["--scheduler", client.scheduler.address]


@pytest.fixture
def make_learner():
    def make(acquisition: str = "qnei", seed: int = 0, q: int = 3) -> PreferenceLearner:
        return PreferenceLearner(LearnerConfig(
            box=ParameterBox.from_bounds(TABLE_I), acquisition=AcquisitionName(acquisition),
            schedule=BatchSchedule(n_initial=4, q=q, n_unique=10), seed=seed))
    return make

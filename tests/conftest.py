from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from robot_io.config import ControllerConfig


@pytest.fixture
def config() -> ControllerConfig:
    return ControllerConfig()


@pytest.fixture
def start(config: ControllerConfig) -> np.ndarray:
    return config.scene.point("robot_start")


@pytest.fixture
def goal(config: ControllerConfig) -> np.ndarray:
    return config.scene.point("handover_point")


# Hypothesis in CI: derandomized (a fixed seed derived from each test, so every run tries the same
# examples), no example database, no deadline (the engine's steps fit the learner); each test sets
# its own bounded ``max_examples``.
settings.register_profile("handover", derandomize=True, database=None, deadline=None,
                          print_blob=True, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("handover")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Tests that use a module-scoped fixture (a whole session run once, a study folder, a learner
    worker) share one xdist worker, so the fixture is built once, not once per worker that happens
    to draw one of them (``make test`` runs ``--dist loadgroup``). Runs before xdist reads the
    groups."""
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        if info is None or item.get_closest_marker("xdist_group"):
            continue
        if any(defs[-1].scope == "module" for defs in info.name2fixturedefs.values() if defs):
            item.add_marker(pytest.mark.xdist_group(item.module.__name__))

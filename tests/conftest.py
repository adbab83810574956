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

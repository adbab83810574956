from __future__ import annotations

import numpy as np
import pytest

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

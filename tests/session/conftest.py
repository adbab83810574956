from __future__ import annotations

import pytest
from support.engine import SHORT_PROTOCOL
from support.runner import Probe

from app.session.config import LabConfig
from app.session.rehearsal import Rehearsal
from app.session.runner import SessionRunner


@pytest.fixture
def rehearsed(tmp_path):
    """A runner on a rehearsal rig (stand-in UR, hand on LSL), the short protocol, the simulated
    participant rating (loaded and Go automatic); the test starts the trials. Yields (runner, probe)."""
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL, "release": {"timeout_s": 2.0}})
    runner = SessionRunner(tmp_path / "study", lab, rehearsal=Rehearsal(lab),
                           realtime_priority=True)
    runner.set_auto(True)
    try:
        yield runner, Probe(runner)
    finally:
        runner.close()

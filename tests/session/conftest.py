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
    participant rating (loaded and Go automatic); the test starts the trials. Yields (runner, probe).

    The release timeout is the product's default (``[release] timeout_s`` = 10 s): a trial whose
    participant pulls must end ``completed``, and the simulated pull comes ``grasp_delay_s`` (0.5 s)
    after the hand reaches H. A short value (it was 2 s) races the machine's load: CI failed under
    load on "a 2 s release timeout". The no-pull test does not need it short: nothing pulls."""
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL})
    runner = SessionRunner(tmp_path / "study", lab, rehearsal=Rehearsal(lab),
                           realtime_priority=True)
    runner.set_auto(True)
    try:
        yield runner, Probe(runner)
    finally:
        runner.close()

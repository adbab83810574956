"""The ur_rtde control worker (robot_io.arms.ur_worker) against the stand-in controller."""

from __future__ import annotations

import logging

import pytest
from support.ur import standin
from support.waiting import wait_for

from robot_io.arms.ur_worker import ControlWorker
from robot_io.errors import ArmFault

pytestmark = [pytest.mark.soak, pytest.mark.standin]

#: Long enough for the stand-in to stall past the call's own wait, short against the suite.
STALL_S = 1.5
CALL_TIMEOUT_S = 0.3


def test_an_answer_that_comes_after_its_call_gave_up_is_never_the_next_calls_answer(caplog):
    """A synchronous stopL sent to a stalled controller gives up after its timeout; its answer
    (None) comes once the controller runs again. The next call, isProgramRunning, must get its own
    answer (True), not that one: read as "not running", it re-uploaded a running script."""
    caplog.set_level(logging.WARNING, logger="robot_io.arms.ur_worker")
    with standin() as ur:
        worker = ControlWorker(ur.host, upper_range_registers=False, timeout=10.0)
        try:
            ur.control("stall", seconds=STALL_S)
            with pytest.raises(ArmFault, match=f"stopL: no answer .* within {CALL_TIMEOUT_S} s"):
                worker.call("stopL", 10.0, False, timeout=CALL_TIMEOUT_S)
            wait_for(lambda: not ur.control("state")["stalled"], "the stand-in's stall to end",
                     seen=lambda: ur.control("state")["events"][-3:])
            assert worker.call("isProgramRunning") is True
        finally:
            worker.close()
    dropped = [r.getMessage() for r in caplog.records if "dropped a late answer" in r.getMessage()]
    assert dropped == ["dropped a late answer of the ur_rtde control process (call 1, ok: None) "
                       "while waiting for call 2, isProgramRunning"]

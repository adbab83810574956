"""The ur_rtde control worker (robot_io.arms.ur_worker) against the stand-in controller."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys

import pytest
from support.processes import alive, describe, still_alive, stopped
from support.ur import standin
from support.waiting import CEILING_S, wait_for

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


#: A rig as far as its arm's worker goes: it starts one, says its pid, and waits.
RIG = """
import sys, time
from robot_io.arms.ur_worker import ControlWorker
worker = ControlWorker(sys.argv[1], upper_range_registers=False, timeout=60.0)
print("rig:", worker.process.pid, flush=True)
time.sleep(600)
"""


def said(rig: subprocess.Popen) -> str:
    """The rig's next line (ur_rtde, in the worker, prints to the same stdout)."""
    for line in rig.stdout:
        if line.startswith("rig: "):
            return line.removeprefix("rig: ").strip()
    raise AssertionError(f"the rig ended (exit code {rig.wait()})")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl(2) is Linux's")
def test_a_worker_that_does_not_run_ends_with_its_rig():
    """The rig is killed while its worker does not run: stopped here (SIGSTOP), as a worker blocked
    in a ur_rtde call that never returns (a dead controller) or in its servoStop. It ends with the
    rig, at once. Before, such a worker stayed for good (seen twice, its parent init), holding the
    arm's control connection: it ended only once it read its pipe's end."""
    with standin() as ur:
        rig = subprocess.Popen([sys.executable, "-c", RIG, ur.host], stdout=subprocess.PIPE,
                               text=True)
        worker = None
        try:
            worker = int(said(rig))
            os.kill(worker, signal.SIGSTOP)
            wait_for(lambda: stopped(worker), "the worker to stop", seen=lambda: describe(worker))
            rig.kill()
            rig.wait()
            assert still_alive([worker], CEILING_S) == []
        finally:
            rig.kill()
            rig.wait()
            if worker is not None and alive(worker):
                os.kill(worker, signal.SIGKILL)

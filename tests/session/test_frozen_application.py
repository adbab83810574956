"""A frozen application stops the arm (issue 25, item 1): its rig sees it stopped, stops the arm and
ends the trial 'stopped' (stored as aborted, and repeated), and the trial says why once the
application runs again. (An application that hangs while it runs: tests/robot_io/rig/test_rig_process.py.)"""

from __future__ import annotations

import pytest
from support.frozen import end, freeze_mid_reach, start_session, stored_trial, thaw
from support.ur import standin
from support.waiting import CEILING_S, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.standin, pytest.mark.soak]

#: The CB-series controller's rate: servo targets per second.
RATE_HZ = 125
#: The rig looks at its application every 0.05 s while nothing comes; the rest of this bound is for
#: the targets in flight and a loaded machine (the rig runs under SCHED_FIFO, the stand-in too) [s].
STOPPED_WITHIN_S = 0.5


@pytest.mark.parametrize("ctrl_z", [False, True], ids=["SIGSTOP", "Ctrl-Z"])
def test_a_frozen_application_has_its_rig_stop_the_arm_and_the_trial_says_why(tmp_path, ctrl_z):
    """Before, the reach went on to H and the arm held there until the release timed out (1128
    servoL after the SIGSTOP in the issue), with nothing able to stop it. Now the controller gets
    at most STOPPED_WITHIN_S of targets after the freeze; the stop is servoStop (a deceleration,
    never a jump). Ctrl-Z (SIGTSTP to the process group) would freeze the rig with the application:
    the rig ignores it, and stops the arm as for SIGSTOP."""
    with standin() as ur:
        run = start_session(tmp_path, ur)
        try:
            frozen = freeze_mid_reach(run, ur, tmp_path, ctrl_z)
            thaw(run)  # the application runs again and records the trial
            outcome = wait_for(lambda: stored_trial(tmp_path / "study" / "F1.sqlite", 1),
                               "trial 1's outcome in the database", timeout=CEILING_S * 2)
        finally:
            end(run)
    assert frozen.targets_after <= STOPPED_WITHIN_S * RATE_HZ, frozen
    assert outcome[0] == "aborted", outcome  # repeated, never rated
    assert outcome[1].startswith("stopped: the application is stopped (Ctrl-Z, SIGSTOP"), outcome
    assert outcome[1].endswith("the rig stopped the arm"), outcome

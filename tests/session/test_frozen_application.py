"""A frozen application stops the arm (issue 25, item 1): its rig hears no heartbeat, stops the
arm and ends the trial 'stopped' (stored as aborted, and repeated), and the trial says why once the
application runs again."""

from __future__ import annotations

import os
import signal

import pytest
from support.frozen import end, freeze_mid_reach, start_session, stored_trial
from support.ur import standin
from support.waiting import CEILING_S, wait_for

from robot_io.rig.messages import APP_SILENCE_S

pytestmark = [pytest.mark.slow, pytest.mark.standin, pytest.mark.soak]

#: The CB-series controller's rate: servo targets per second.
RATE_HZ = 125


def test_a_frozen_application_has_its_rig_stop_the_arm_and_the_trial_says_why(tmp_path):
    """Before, the reach went on to H and the arm held there until the release timed out (1128
    servoL after the SIGSTOP in the issue), with nothing able to stop it. Now the controller gets
    at most one second of targets after the freeze: APP_SILENCE_S (0.5 s) for the rig to miss the
    application's heartbeat, and the rest for the heartbeat's period, the rig's look and the
    targets in flight; the stop is servoStop (a deceleration, never a jump)."""
    with standin() as ur:
        run = start_session(tmp_path, ur)
        try:
            frozen = freeze_mid_reach(run, ur, tmp_path)
            os.kill(run.pid, signal.SIGCONT)  # the application runs again and records the trial
            outcome = wait_for(lambda: stored_trial(tmp_path / "study" / "F1.sqlite", 1),
                               "trial 1's outcome in the database", timeout=CEILING_S * 2)
        finally:
            end(run)
    assert frozen.targets_after <= 2 * APP_SILENCE_S * RATE_HZ, frozen
    assert outcome[0] == "aborted", outcome  # repeated, never rated
    assert outcome[1].startswith("stopped: the application sent nothing for"), outcome
    assert outcome[1].endswith("the rig stopped the arm"), outcome

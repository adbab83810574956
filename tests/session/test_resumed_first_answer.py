"""A session resumed by a fresh process takes the participant's first answer at once.

After a restart, the first placement used to start the participant's learner process on the engine
thread before the answer was published: the tablet kept its scale, with Confirm enabled, for as long
as a first learner takes to import (13–18 s on a lab's machine). The learner now starts when the
next θ is planned, and the tablet says "Please wait" meanwhile (benchmarks/first_confirm_after_restart.py
measures the tap-to-screen time in a browser).
"""

from __future__ import annotations

import threading

from support.between import Between
from support.engine import SESSION_CONTROLLER, SHORT_PROTOCOL, closed_session
from support.runner import READY_CEILING_S, Probe

from app.learning.worker import LearnerClient
from app.protocol.state import Step
from app.session.config import LabConfig
from app.session.runner import SessionRunner

CODE = "R01"


def test_the_first_placement_after_a_restart_is_taken_while_the_learner_is_still_starting(tmp_path):
    study = tmp_path / "study"
    closed_session(study, CODE, until=Step.PLACE)  # stopped at the scale, as Ctrl-C leaves it
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL,
                                    "loop": {"rate_hz": SESSION_CONTROLLER.loop.rate_hz}})
    # The learner's start is held on whichever thread reaches it first (the engine thread).
    learner_start = Between(LearnerClient._start, "self._process.start()")
    with learner_start.tracing():
        runner = SessionRunner(study, lab, realtime=False)
    probe = Probe(runner)
    try:
        runner.open(CODE)
        slot = runner.view.state.slot
        assert runner.view.step is Step.PLACE and slot.learner_index is not None
        learner_start.arm()
        threading.Thread(target=runner.place, args=(slot.interaction, 0.3), daemon=True).start()
        taken = probe.wait(lambda v: learner_start.holding.is_set() and v.step is not Step.PLACE,
                           timeout=30.0, what="the placement taken while the learner's start is held")
        assert taken.step is Step.PLAN
        learner_start.release()
        planned = probe.wait(lambda v: v.step is Step.READY, timeout=READY_CEILING_S,
                             what="the next θ from the learner, once its start is let go")
        assert planned.learner_fault is None
    finally:
        learner_start.release()
        runner.close()

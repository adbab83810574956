"""A learner whose first reply comes later than the plan's timeout (a loaded machine: importing
BoTorch in the worker took 47 s under a load of 11–15): the session plans a flagged fallback θ and
goes on; it stores no learner snapshot until there is a state to store, and resumes."""

from __future__ import annotations

from support.engine import drive_until, new_engine

from app.protocol.engine import SessionEngine
from app.protocol.state import Step


def test_a_first_reply_later_than_the_plan_gives_a_fallback_and_the_session_goes_on(tmp_path):
    engine = new_engine(tmp_path, "L01")
    try:
        # Timeout 0: the worker process cannot have answered, the reply is late by construction.
        planned = engine.plan_next(timeout=0.0)
        assert planned.fallback and engine.state.step is Step.READY
        assert engine.store.rows("learner_snapshots") == []  # no state yet: nothing to store
    finally:
        engine.close()
    resumed = SessionEngine.resume(tmp_path, "L01")
    try:
        assert resumed.state.planned[1] == planned  # the fallback θ was kept
        drive_until(resumed, Step.DONE)
        snapshots = resumed.store.rows("learner_snapshots")
        assert snapshots and all(row.state for row in snapshots)
    finally:
        resumed.close()

"""The session's background worker: it has the learner plan the next θ when the session waits for
one, lets the simulated participant place, rate and answer when it is switched on and, headless
(``run-session``), acts as the simulated experimenter: it starts every trial, recovers the arm
after a fault that needs no person, and gives up after :data:`MAX_FAILED_TRIALS` trials in a row
that did not complete.

It runs on its own thread ("session-worker") and uses only the session runner's public API: it is
woken by every published view, decides from the view alone, and acts through the runner's actions
as a screen would. Its count of failed trials is its own, kept on its thread (docs/architecture.md,
"Threads and who owns what")."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Protocol

from app.protocol.errors import RefusedAction
from app.protocol.state import PARTICIPANT_STEPS, Step
from app.session.view import RunnerView
from robot_io.rig.client import RigClient
from session_store.models import Trial

log = logging.getLogger(__name__)


class Runner(Protocol):
    """What the autopilot may use of the session runner: its public API, no more."""

    realtime: bool
    auto_experimenter: bool

    @property
    def view(self) -> RunnerView: ...
    @property
    def rig(self) -> RigClient | None: ...
    def subscribe(self, listener: Callable[[RunnerView], None]) -> None: ...
    def plan_next(self) -> None: ...
    def simulated_turn(self, step: Step) -> None: ...
    def start_trial(self) -> Trial: ...
    def recover_arm(self, inspected: bool = True) -> None: ...
    def note(self, message: str) -> None: ...
    def give_up(self, reason: str) -> None: ...

#: The simulated participant's pause before it rates, so that each screen is seen [s].
AUTO_DELAY_S = 0.6
#: The simulated experimenter gives up after this many trials in a row that did not complete.
MAX_FAILED_TRIALS = 5


class Autopilot:
    """The background worker of ``runner``; started at once, ended by :meth:`stop` and :meth:`join`."""

    def __init__(self, runner: Runner) -> None:
        self._runner = runner
        self._wake = threading.Event()
        self._closing = threading.Event()
        # the simulated experimenter's count, for the session of ``_code`` (only this thread writes)
        self._code: str | None = None
        self._started: int | None = None  # the trial it started last, until its end is seen
        self._failed_in_a_row = 0
        runner.subscribe(lambda _view: self._wake.set())
        self._thread = threading.Thread(target=self._work, name="session-worker", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Do nothing more (the runner closes)."""
        self._closing.set()
        self._wake.set()

    def join(self) -> None:
        """Wait for the worker's end (after :meth:`stop` and the runner's refusal of every job)."""
        self._thread.join()

    def _work(self) -> None:
        while not self._closing.is_set():
            self._wake.wait()
            self._wake.clear()
            try:
                while not self._closing.is_set() and self._next_job():
                    pass
            except RefusedAction as exc:  # the session closed under the job (SessionClosed), or
                if self._closing.is_set():  # another refusal: looked at again on the next view
                    return
                log.warning("the session worker's job was refused: %s", exc)

    def _next_job(self) -> bool:
        """Act once on the latest view; True if it should look again at once."""
        runner = self._runner
        view = runner.view
        if view.state is None or view.failed is not None:
            return False
        step = view.step
        if step is Step.PLAN:
            runner.plan_next()
            return False
        if view.auto and step in PARTICIPANT_STEPS:
            if runner.realtime:
                time.sleep(AUTO_DELAY_S)
            try:
                runner.simulated_turn(step)
            except RefusedAction as exc:
                log.warning("the simulated participant's answer was refused: %s", exc)
                return False
            return True
        if runner.auto_experimenter and step is Step.READY and not view.state.paused:
            return self._auto_start(view)
        return False

    def _count(self, view: RunnerView) -> None:
        """The end of the trial it started last, once the session is ready again: a completed
        trial resets the count of trials in a row that did not complete, any other adds one."""
        if view.code != self._code:  # another session
            self._code, self._started, self._failed_in_a_row = view.code, None, 0
        ended = next((t for t in view.trials if t.trial_index == self._started), None)
        if ended is None or ended.outcome is None:  # its end was not stored: not counted
            return
        self._started = None
        self._failed_in_a_row = 0 if ended.outcome.value == "completed" else self._failed_in_a_row + 1

    def _auto_start(self, view: RunnerView) -> bool:
        """The simulated experimenter's Start (after Recover arm when the arm has a fault that
        needs no person); True to try again at once after a refused Start."""
        runner = self._runner
        self._count(view)
        if self._failed_in_a_row >= MAX_FAILED_TRIALS:
            runner.give_up(f"{MAX_FAILED_TRIALS} trials in a row did not complete; the last: "
                           f"{view.trials[-1].reason if view.trials else '?'}")
            return False
        rig = runner.rig
        if view.arm_fault is not None and rig is not None and rig.alive:
            try:
                runner.recover_arm(inspected=False)  # never a safety stop: that needs a person
            except RefusedAction as exc:
                runner.give_up(f"the arm needs a person: {exc}")
                return False
        try:
            self._started = runner.start_trial().trial_index
        except RefusedAction as exc:
            self._failed_in_a_row += 1
            runner.note(str(exc))
            return self._failed_in_a_row < MAX_FAILED_TRIALS
        return False

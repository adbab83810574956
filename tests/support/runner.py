"""Watching a SessionRunner from a test: every published view, and waiting for one that matters."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from app.session.runner import RunnerView, SessionRunner
from support.waiting import CEILING_S, WaitTimeout


def describe(view: RunnerView) -> str:
    """What a screen would show of ``view``, for a wait that gave up: the step and stage, the
    trials so far (index, interaction, attempt, outcome, reason), why the hand is not ready, the
    faults, the last messages."""
    trials = [(t.trial_index, t.interaction, t.attempt, t.outcome and t.outcome.value, t.reason)
              for t in view.trials]
    return (f"step {view.step}, stage {view.stage}, stop {view.stop}, waiting for "
            f"{view.waiting_for}, ready_wait {view.ready_wait!r}, arm fault {view.arm_fault!r}, "
            f"learner {view.learner} (fault {view.learner_fault!r}), failed {view.failed!r}, "
            f"trials {trials}, messages {view.messages}")


class Probe:
    """Subscribes to a runner; :meth:`wait` blocks until a view satisfies a condition."""

    def __init__(self, runner: SessionRunner) -> None:
        self.runner = runner
        self.views: list[RunnerView] = []
        self._changed = threading.Condition()
        runner.subscribe(self._seen)

    def _seen(self, view: RunnerView) -> None:
        with self._changed:
            self.views.append(view)
            self._changed.notify_all()

    def wait(self, condition: Callable[[RunnerView], bool], timeout: float = CEILING_S,
             what: str = "the condition") -> RunnerView:
        """The first published view that satisfies ``condition`` (woken by each new view).
        ``timeout`` is a ceiling for a hung session, not a measurement; when it passes, the
        :class:`WaitTimeout` names ``what`` and describes the last view."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                view = self.runner.view
                if condition(view):
                    return view
                left = deadline - time.monotonic()
                if left <= 0:
                    raise WaitTimeout(f"gave up after {timeout:g} s waiting for {what}; last view: "
                                      f"{describe(view)}")
                self._changed.wait(min(left, 0.1))

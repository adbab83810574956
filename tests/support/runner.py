"""Watching a SessionRunner from a test: every published view, and waiting for one that matters."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from app.session.runner import RunnerView, SessionRunner


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

    def wait(self, condition: Callable[[RunnerView], bool], timeout: float = 60.0,
             what: str = "the condition") -> RunnerView:
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                view = self.runner.view
                if condition(view):
                    return view
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"timed out waiting for {what}; last view: step "
                                         f"{view.step}, stage {view.stage}, messages "
                                         f"{view.messages}, fault {view.arm_fault}")
                self._changed.wait(min(left, 0.1))

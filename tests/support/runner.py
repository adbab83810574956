"""Watching a SessionRunner from a test: every published view, and waiting for one that matters."""

from __future__ import annotations

import sys
import threading
import time
import traceback
from collections.abc import Callable
from pathlib import Path

from app.session.config import LabConfig
from app.session.runner import PLAN_TIMEOUT_S, RunnerView, SessionRunner
from session_store.models import Trial
from support.engine import SESSION_CONTROLLER
from support.repeats import TRIAL_ATTEMPTS, starved, unless_starved
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


#: The ceiling of a wait for the next θ ('ready'): above the product's own PLAN_TIMEOUT_S, after
#: which a learner late with its reply (under load its first start took over a minute) is replaced
#: by a flagged fallback θ — the wait must see that happen, not give up at the same moment.
READY_CEILING_S = PLAN_TIMEOUT_S + CEILING_S
#: The project's packages: a thread with one of their frames on its stack is doing the project's work.
PACKAGES = tuple(str(Path(__file__).resolve().parents[2] / name) for name in
                 ("app", "robot_io", "session_store"))


def busy_threads(frames: int = 6) -> str:
    """Where this process's threads that are in the project's code are now (their innermost
    ``frames`` frames), for a wait that gave up on an action that never finished: a GUI callback
    blocked on the engine thread, and the engine thread itself, show where they stand."""
    lines = []
    current = sys._current_frames()
    for thread in threading.enumerate():
        frame = current.get(thread.ident)
        stack = traceback.extract_stack(frame) if frame is not None else []
        if any(entry.filename.startswith(PACKAGES) for entry in stack):
            where = " < ".join(f"{Path(entry.filename).name}:{entry.lineno} {entry.name}"
                               for entry in reversed(stack[-frames:]))
            lines.append(f"[{thread.name}] {where}")
    return "\n".join(lines) or "no thread is in the project's code"


def headless_runner(study: Path, protocol: dict) -> tuple[SessionRunner, Probe]:
    """A runner of ``study`` on simulated time whose trials the simulated experimenter starts
    (the [protocol] table ``protocol``, on the sessions' controller rate), and its probe."""
    lab = LabConfig.model_validate({"protocol": protocol,
                                    "loop": {"rate_hz": SESSION_CONTROLLER.loop.rate_hz}})
    runner = SessionRunner(study, lab, realtime=False, auto_experimenter=True)
    return runner, Probe(runner)


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


def ready(view: RunnerView) -> bool:
    """The session waits for Start: the next θ is planned."""
    return view.step is not None and view.step.value == "ready"


def ended(view: RunnerView, index: int) -> Trial | None:
    """Trial ``index`` of ``view`` once it has an outcome, else None."""
    return next((t for t in view.trials if t.trial_index == index and t.outcome), None)


def run_trial(runner: SessionRunner, probe: Probe, attempts: int = TRIAL_ATTEMPTS) -> Trial:
    """Start a trial and return it once ended; a trial the starved machine aborted
    (support.repeats) is recovered from as an experimenter would (Recover when the arm has a fault
    or the rig ended) and started again, at most ``attempts`` times."""

    def attempt() -> tuple[Trial, str | None]:
        probe.wait(ready, what="ready for a trial", timeout=READY_CEILING_S)
        index = runner.start_trial().trial_index
        view = probe.wait(lambda v: ended(v, index) is not None, what=f"trial {index} ended",
                          timeout=CEILING_S + READY_CEILING_S)
        trial = ended(view, index)
        assert trial is not None and trial.outcome is not None
        if trial.outcome.value == "completed" or not starved(trial.reason):
            return trial, None  # the test judges any other end
        if view.arm_fault or runner.rig is None or not runner.rig.alive:
            runner.recover_arm(inspected=True)
        return trial, f"trial {index} {trial.outcome.value}: {trial.reason}"

    return unless_starved("a trial", attempt, attempts)

"""A trial on the wall clock that the machine, not the code under test, ended: started again.

On a loaded 2-core machine (CI beside other work, a VM that the host holds still for seconds) even a
rig under SCHED_FIFO can be starved past its limits: the stand-in controller sends no state for
0.1 s, the tracker's samples arrive late, and the trial is aborted, as the rig must abort it. A test
whose subject is not that trial's outcome (a replay of it, a fault injected into it) repeats it as
an experimenter would, at most :data:`TRIAL_ATTEMPTS` times. Each repeat is a warning in the
suite's summary (what ended the trial), so a run that needed one says so; a trial aborted every time
fails the test with every reason.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")

#: How many times a test starts the trial it needs before it fails.
TRIAL_ATTEMPTS = 3
#: What the rig says when the machine starved it (its own words): the stand-in controller sent no
#: state for STATE_SILENCE_S, or the hand's samples grew older than the staleness limit. Only
#: these are repeated; any other end of the trial is the test's to judge.
STARVED = ("sent no new state", "no valid hand sample")


def starved(reason: str | None) -> bool:
    """Whether a trial that ended for ``reason`` was ended by a starved machine (:data:`STARVED`)."""
    return reason is not None and any(words in reason for words in STARVED)


class MachineEndedTrial(UserWarning):
    """A trial a test needed was ended by the machine's load and started again."""


def unless_starved(what: str, attempt: Callable[[], tuple[T, str | None]],
                   attempts: int = TRIAL_ATTEMPTS) -> T:
    """``attempt()`` until it gives no reason to repeat it, and what it gave then: it returns its
    result and None (the test judges the result), or a reason to repeat (the machine ended
    ``what`` first: it has already recovered for the next attempt). Each repeat is a
    :class:`MachineEndedTrial` warning in the suite's summary; after ``attempts`` the test fails
    naming every reason."""
    reasons = []
    for _ in range(attempts):
        result, repeat = attempt()
        if repeat is None:
            return result
        reasons.append(repeat)
        warnings.warn(MachineEndedTrial(f"{what} ended before its subject ({repeat}): repeated"),
                      stacklevel=2)
    raise AssertionError(f"{what}: all {len(reasons)} attempts ended before their subject: "
                         + "; ".join(f"{i}. {r}" for i, r in enumerate(reasons, 1)))

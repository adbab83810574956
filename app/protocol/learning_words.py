"""Where learning stands and why it stopped, in words an experimenter can act on (issues 40, 45,
46).

Every sentence about the learner's progress is made here, for the dashboard (the Devices panel's
learning line, the status line and the Recent events after a stop), for the ``learning_stopped``
event's reason (which the report shows), for the report's "Learning ended" and "stopping rule"
columns and for ``handover replay-stop``. A new stopping rule words itself here too.

Two rules (docs/learning.md). ``stop_when_settled``: the signal is the posterior probability that
θ* is *close to the participant's best*: its regret is at most ε, ε set so that in a choice between
their very best handover and θ* the participant would pick the best at most ``settled_preference``
of the time. ``stop_when_no_gain``: the signal is how likely the next batch is (at most, a bound)
to find a handover the participant would pick over θ* more than ``gain_preference`` of the time.
The words say that, not "ε", "regret" or "gain".
"""

from __future__ import annotations

import math

from app.learning.config import GainRule, StoppingRule, preferred_for
from app.learning.models import NextBatchGain, Settledness
from app.protocol.state import SessionState, Step
from app.protocol.study_config import StudyConfig
from session_store.models import Event, LearnerSnapshotRow
from session_store.vocabulary import Phase

#: θ* "has not moved" over a batch when it moved less than this in the θ box scaled to [0, 1]
#: per parameter (a tenth of each parameter's range).
UNCHANGED = 0.1


def _percent(share: float) -> str:
    return f"{share * 100:.0f} %"


def _close(preference: float) -> str:
    """What "close to the participant's best" means, in their terms."""
    return (f"they would pick their very best handover over it at most {_percent(preference)} of "
            "the time")


def _found(preference: float) -> str:
    """What a handover worth another batch is, in the participant's terms."""
    return (f"find a handover the participant would pick over the learner's best guess more than "
            f"{_percent(preference)} of the time")


def _batches(count: int) -> str:
    return f"{count} batch{'' if count == 1 else 'es'}"


def _handovers(count: int) -> str:
    return f"{count} handover{'' if count == 1 else 's'}"


def rule_words(rule: StoppingRule | GainRule) -> str:
    """A stopping rule as a lab pre-registers it (the report's learning table, replay-stop), e.g.
    "stop once 50 % sure that the learner's best guess is close to the participant's best (they
    would pick their very best handover over it at most 80 % of the time), from batch 1 on"."""
    if isinstance(rule, GainRule):
        return (f"stop once the next batch is at most {_percent(rule.chance)} likely to "
                f"{_found(rule.preference)}, from batch {rule.min_batches} on")
    return (f"stop once {_percent(rule.threshold)} sure that the learner's best guess is close to "
            f"the participant's best ({_close(preferred_for(rule.epsilon))}), from batch "
            f"{rule.min_batches} on")


def stop_reason(config: StudyConfig, batches: int, signal: float) -> str:
    """Why learning stopped after ``batches`` learning batches at the rule's ``signal`` (settled:
    how sure; gain: how likely the next batch finds better): the ``learning_stopped`` event's
    reason."""
    rule = config.stopping_rule()
    assert rule is not None, "a session without a stopping rule never stops early"
    done = f"after learning batch {batches} of {config.learning_batches}"
    if isinstance(rule, GainRule):
        return (f"{done} the next batch was at most {_percent(signal)} likely to "
                f"{_found(rule.preference)}; it stops at {_percent(rule.chance)} or less, from "
                f"batch {rule.min_batches} on")
    return (f"{done} the learner was {_percent(signal)} sure that its best guess is close to the "
            f"participant's best ({_close(preferred_for(rule.epsilon))}); it stops at "
            f"{_percent(rule.threshold)}, from batch {rule.min_batches} on")


def learning_batches_done(state: SessionState) -> int:
    """Learning batches whose every handover is placed (or hinted) — those the learner has."""
    current = state.slot.interaction if state.slot is not None else len(state.slots) + 1
    return sum(s.phase is Phase.LEARNING and s.position == s.batch_size
               and s.interaction < current for s in state.slots)


def stop_headline(state: SessionState) -> str | None:
    """The stop in one line for the status line and Recent events, e.g. "Learning stopped early
    after batch 1 of 4: sure enough of the best handover, 9 handovers fewer"; None: learning did
    not stop early."""
    if state.stopped_after is None:
        return None
    learning = [s for s in state.slots if s.phase is Phase.LEARNING]
    last = state.slots[state.stopped_after - 1]
    skipped = len(state.slots) - state.interactions
    return (f"Learning stopped early after batch {last.batch} of "
            f"{max((s.batch for s in learning), default=0)}: the learner is sure enough of the "
            f"best handover, {_handovers(skipped)} fewer")


#: What a stopped session was waiting for, in the report's words.
WAITING = {Step.PLAN: "waiting for the learner's next handover", Step.READY: "waiting for Start",
           Step.RUNNING: "during a trial", Step.PLACE: "waiting for a placement",
           Step.HINT: "waiting for a hint", Step.RATE: "waiting for a rating",
           Step.ANSWER: "waiting for the questionnaire", Step.DONE: "complete"}


def learning_end(state: SessionState, config: StudyConfig, stopped: str | None,
                 paused: str | None) -> tuple[str, str]:
    """How a session's learning ended and why, for the report: "early" (``stopped``: the recorded
    reason), "at the schedule's end", "interrupted after 4 of 25" or "not started" (``paused``:
    the pause's reason, when the session is paused)."""
    if stopped is not None:
        return "early", stopped
    slot = state.slot
    if slot is None or slot.learner_index is None:
        return "at the schedule's end", never_stopped(config.stopping_rule())
    where = WAITING[state.step] + ("" if paused is None else f"; paused: {paused}")
    if state.completed == 0:
        return "not started", f"no handover was completed ({where})"
    learned = sum(s.learner_index is not None for s in state.slots)
    return (f"interrupted after {state.completed} of {learned}",
            f"the session stopped before learning ended, at handover {slot.interaction} of "
            f"{state.interactions} ({where})")


def never_stopped(rule: StoppingRule | GainRule | None) -> str:
    """Why a session that learned to the schedule's end did not stop early."""
    if rule is None:
        return "the fixed schedule (no stopping rule)"
    if isinstance(rule, GainRule):
        return ("the fixed schedule: the next batch never became unlikely enough to find a better "
                f"handover (at most {_percent(rule.chance)})")
    return f"the fixed schedule: the learner was never sure enough to stop ({_percent(rule.threshold)})"


def recorded_stop(events: list[Event]) -> str | None:
    """The reason the ``learning_stopped`` event of ``events`` records (None: learning did not
    stop early)."""
    return next((e.payload["reason"] for e in reversed(events) if e.kind == "learning_stopped"),
                None)


def learning_line(state: SessionState, config: StudyConfig, signal: Settledness | None,
                  stopped: str | None, snapshots: list[LearnerSnapshotRow],
                  gain: NextBatchGain | None = None) -> str | None:
    """Where learning stands now (the dashboard's learning line), from the session's ``state``,
    the learner's latest stopping signals (``signal``: how settled θ* is; ``gain``: what the next
    batch may gain, with ``stop_when_no_gain``), the recorded reason it ``stopped`` early (None: it
    did not) and the learner ``snapshots`` in order; None before the first learning batch ends."""
    headline = stop_headline(state)
    if stopped is not None and headline is not None:
        return f"{headline} ({stopped})."
    rule = config.stopping_rule()
    if (gain if isinstance(rule, GainRule) else signal) is None:
        return None
    done = learning_batches_done(state)
    unchanged = unchanged_batches(state, config, snapshots)
    guess = ("it is the learner's first best guess" if unchanged is None else
             f"the learner's best guess has not moved for {_batches(unchanged)}" if unchanged else
             "the learner's best guess moved in the last batch")
    if isinstance(rule, GainRule) and gain is not None:
        where = (f"the next batch is at most {_percent(gain.chance(rule.epsilon))} likely to "
                 f"{_found(rule.preference)}")
        stops = f"once that is {_percent(rule.chance)} or less"
    else:
        assert signal is not None, "checked above"
        where = (f"it is {_percent(signal.probability_within(config.settled_epsilon))} sure that "
                 f"this guess is close to the participant's best "
                 f"({_close(config.settled_preference)})")
        stops = f"once it is {_percent(config.settled_threshold)} sure"
    left = config.learning_batches - done
    if rule is None:
        goes_on = f"learning runs all {config.learning_batches} batches (no stopping rule)"
    elif left == 0:
        goes_on = "that was the last learning batch"
    else:
        goes_on = (f"learning stops early {stops} (from batch {rule.min_batches} on); until then "
                   f"it goes on, at most {left} more batch{'' if left == 1 else 'es'}")
    return (f"After learning batch {done} of {config.learning_batches}: {guess}; {where}. "
            f"{goes_on[0].upper()}{goes_on[1:]}.")


def unchanged_batches(state: SessionState, config: StudyConfig,
                      snapshots: list[LearnerSnapshotRow]) -> int | None:
    """Learning batches in a row, up to now, after which θ* stayed within :data:`UNCHANGED` (in
    the θ box scaled to [0, 1]) of where it was after the batch before (``snapshots``: the
    learner's, in order); None after the first batch (nothing to compare with)."""
    ends = {s.interaction - 1 for s in state.slots if s.phase is Phase.LEARNING
            and s.position == 1}
    bounds = config.theta_bounds
    stars = [(a, delta, k) for r in snapshots
             if r.after_interaction in ends | {max(ends, default=0) + config.batch_size}
             and (a := r.theta_star_a) is not None and (delta := r.theta_star_delta) is not None
             and (k := r.theta_star_k) is not None]
    unit = [[(v - low) / (high - low) for v, (low, high) in zip(star, bounds.values(),
                                                                 strict=True)]
            for star in stars]
    if len(unit) < 2:
        return None
    count = 0
    for before, after in zip(reversed(unit[:-1]), reversed(unit[1:]), strict=True):
        if math.dist(before, after) > UNCHANGED:
            break
        count += 1
    return count

"""The dashboard's line about how settled the learner is (issue 40), in plain words, e.g.

    "the learner's choice has not changed in 2 batches; 92 % sure that the best handover would be
    preferred to it at most 60 % of the time; learning stops at 90 % after at least 2 batches"

The runner's view shows :func:`learning_line` of its engine; it reads the stored θ* after each
learning batch and the engine's latest stopping signal (:class:`~app.learning.models.Settledness`).
"""

from __future__ import annotations

import math

from app.learning.config import GainRule
from app.learning.models import NextBatchGain
from app.protocol.engine import SessionEngine
from session_store.vocabulary import Phase

#: θ* "has not changed" over a batch when it moved less than this in the θ box scaled to [0, 1]
#: per parameter (a tenth of each parameter's range).
UNCHANGED = 0.1


def learning_line(engine: SessionEngine) -> str | None:
    """What the learner's stopping signal says now; None before the first learning batch ends."""
    stopped = next((e.payload["reason"] for e in reversed(engine.store.events())
                    if e.kind == "learning_stopped"), None)
    if stopped is not None:
        return f"learning stopped early, {stopped}"
    rule = engine.config.stopping_rule()
    if isinstance(rule, GainRule):
        return None if engine.gain is None else gain_words(engine.gain, rule)
    signal = engine.settledness
    if signal is None:
        return None
    unchanged = unchanged_batches(engine)
    choice = ("the learner's first choice" if unchanged is None else
              f"the learner's choice has not changed in {unchanged} batch"
              f"{'es' if unchanged != 1 else ''}" if unchanged else
              "the learner's choice moved in the last batch")
    sure = (f"{signal.probability_within(engine.config.settled_epsilon):.0%} sure that the best "
            f"handover would be preferred to it at most {engine.config.settled_preference:.0%} of "
            "the time")
    stops = ("learning runs the whole schedule (stop_when_settled off)" if rule is None else
             f"learning stops at {rule.threshold:.0%} after at least {rule.min_batches} batches")
    return f"{choice}; {sure}; {stops}"


def gain_words(gain: NextBatchGain, rule: GainRule) -> str:
    """With ``[protocol] stop_when_no_gain`` (issue 46): what the next batch may find, and when
    learning stops, e.g. "the next batch is at most 35 % likely to find a handover preferred to the
    learner's choice more than 80 % of the time; learning stops at 50 % or less after at least 1
    batch"."""
    batches = f"{rule.min_batches} batch{'es' if rule.min_batches != 1 else ''}"
    return (f"the next batch is at most {gain.chance(rule.epsilon):.0%} likely to find a handover "
            f"preferred to the learner's choice more than {rule.preference:.0%} of the time; "
            f"learning stops at {rule.chance:.0%} or less after at least {batches}")


def unchanged_batches(engine: SessionEngine) -> int | None:
    """Learning batches in a row, up to now, after which θ* stayed within :data:`UNCHANGED` (in
    the θ box scaled to [0, 1]) of where it was after the batch before; None after the first
    batch (nothing to compare with)."""
    ends = {s.interaction - 1 for s in engine.slots if s.phase is Phase.LEARNING
            and s.position == 1}
    bounds = engine.config.theta_bounds
    stars = [(r.theta_star_a, r.theta_star_delta, r.theta_star_k)
             for r in engine.store.rows("learner_snapshots", order_by="after_interaction")
             if r.after_interaction in ends | {max(ends, default=0) + engine.config.batch_size}
             and r.theta_star_a is not None]
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

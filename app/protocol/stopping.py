"""Whether learning stops after a batch, as the events that record it (``[protocol]
stop_when_settled``, issue 40; ``stop_when_no_gain``, issue 46).

After every batch of a session with a stopping rule, :func:`check` turns the learner's signals
(how settled θ* is, :mod:`app.learning.settled`; what the next batch may gain,
:mod:`app.learning.gain`) into a ``learning_checked`` event (the rule, its signal, whether it stops)
and, when the rule stops learning, a ``learning_stopped`` event with the reason in words
(:mod:`app.protocol.learning_words`). The session's database so holds every batch's signal and why
learning ended.
"""

from __future__ import annotations

from app.learning.config import GainRule, StoppingRule
from app.learning.models import NextBatchGain, Settledness
from app.protocol import events as ev
from app.protocol.learning_words import stop_reason
from app.protocol.study_config import StudyConfig
from session_store.vocabulary import Actor


def check(config: StudyConfig, after: int, batches: int, settled: Settledness | None,
          gain: NextBatchGain | None, *, may_stop: bool = True
          ) -> list[ev.LearningChecked | ev.LearningStopped]:
    """The events of the check after the batch ending with interaction ``after`` (``batches``
    learning batches done): none without a rule or without its signal (a late learner's
    fallback), else ``learning_checked`` and, if the rule stops learning (and ``may_stop``: not
    after the schedule's last batch), ``learning_stopped``."""
    rule = config.stopping_rule()
    if isinstance(rule, GainRule) and gain is not None:
        signal, stops = gain.chance(rule.epsilon), rule.stops(batches, gain)
        checked = ev.LearningChecked(actor=Actor.LEARNER, after_interaction=after,
                                     batches=batches, rule="gain", signal=signal, gain=gain.gain,
                                     epsilon=rule.epsilon, stops=may_stop and stops)
    elif isinstance(rule, StoppingRule) and settled is not None:
        signal, stops = settled.probability_within(rule.epsilon), rule.stops(batches, settled)
        checked = ev.LearningChecked(actor=Actor.LEARNER, after_interaction=after,
                                     batches=batches, rule="settled", signal=signal,
                                     epsilon=rule.epsilon, stops=may_stop and stops)
    else:
        return []
    if not checked.stops:
        return [checked]
    return [checked, ev.LearningStopped(
        actor=Actor.LEARNER, after_interaction=after, batches=batches, rule=checked.rule,
        probability=signal, epsilon=rule.epsilon,
        threshold=rule.chance if isinstance(rule, GainRule) else rule.threshold,
        min_batches=rule.min_batches, reason=stop_reason(config, batches, signal))]

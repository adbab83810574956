"""Issue 45, item 16: the learning line in words an experimenter can act on — where learning
stands (which batch, whether the best guess still moves, how sure the learner is in the
participant's terms), what happens next (it goes on, how many batches at most, or it stops) and,
after an early stop, why, in the same terms. No "ε", "regret" or "θ*" in them."""

from __future__ import annotations

import re

from support.engine import study_config

from app.learning.models import NextBatchGain, Settledness
from app.protocol.learning_words import (
    learning_line,
    never_stopped,
    rule_words,
    stop_headline,
    stop_reason,
)
from app.protocol.plan import protocol_slots
from app.protocol.state import SessionState
from session_store.models import LearnerSnapshotRow

STOPPING = {"stop_when_settled": True, "settled_threshold": 0.9, "settled_min_batches": 2,
            "settled_preference": 0.6}
#: Words the experimenter should not have to decode.
JARGON = re.compile(r"ε|epsilon|regret|θ\*|posterior")


def signal(sure: int) -> Settledness:
    """A stopping signal: ``sure`` of 100 posterior draws put θ*'s regret within ε (any ε up to 1)."""
    return Settledness(probability=sure / 100, epsilon=0.36,
                       regrets=(0.0,) * sure + (2.0,) * (100 - sure), theta={"a": 1.0})


def star(after: int, a: float) -> LearnerSnapshotRow:
    return LearnerSnapshotRow(after_interaction=after, theta_star_a=a, theta_star_delta=0.0,
                              theta_star_k=5.0, utility_mean=0.0, fit_failed=False, message=None,
                              n_points=after, n_comparisons=after, state="{}")


def test_the_line_says_where_learning_stands_and_what_comes_next():
    config = study_config(**STOPPING)  # the paper's counts: 5 initial, 4 learning batches of 5
    state = SessionState(slots=protocol_slots(config), cursor=15)  # batch 3 opens: 2 are done
    stars = [star(5, 3.0), star(10, 3.1), star(15, 3.05)]  # it moved less than a tenth twice
    line = learning_line(state, config, signal(42), None, stars)
    assert line == (
        "After learning batch 2 of 4: the learner's best guess has not moved for 2 batches; it is "
        "42 % sure that this guess is close to the participant's best (they would pick their very "
        "best handover over it at most 60 % of the time). Learning stops early once it is 90 % "
        "sure (from batch 2 on); until then it goes on, at most 2 more batches.")
    moved = learning_line(state, config, signal(42), None, [star(5, 3.0), star(10, 3.1),
                                                            star(15, 9.0)])
    assert "the learner's best guess moved in the last batch" in moved
    fixed = learning_line(state, study_config(), signal(42), None, stars)
    assert fixed.endswith("Learning runs all 4 batches (no stopping rule).")
    assert not JARGON.search(line + fixed)
    assert learning_line(SessionState(slots=state.slots, cursor=6), config, None, None, []) is None


def test_a_stop_says_why_in_the_same_terms_and_how_much_it_saved():
    config = study_config(**STOPPING)
    reason = stop_reason(config, 2, 0.93)
    assert reason == ("after learning batch 2 of 4 the learner was 93 % sure that its best guess "
                      "is close to the participant's best (they would pick their very best "
                      "handover over it at most 60 % of the time); it stops at 90 %, from batch 2 "
                      "on")
    state = SessionState(slots=protocol_slots(config), cursor=25, stopped_after=15)
    assert stop_headline(state) == ("Learning stopped early after batch 2 of 4: the learner is "
                                    "sure enough of the best handover, 10 handovers fewer")
    assert learning_line(state, config, signal(93), reason, []) == \
        f"{stop_headline(state)} ({reason})."
    assert not JARGON.search(reason)


GAIN = {"stop_when_no_gain": True, "gain_chance": 0.2, "gain_preference": 0.8,
        "gain_min_batches": 1}


def gain(chance: float, config) -> NextBatchGain:
    """What the next batch may gain, such that its bound (q − 1)·g/ε is ``chance`` under ``config``'s
    rule."""
    rule = config.stopping_rule()
    return NextBatchGain(gain=chance * rule.epsilon / 4, queries=4, theta={"a": 1.0},
                         candidate={"a": 2.0})


def test_the_expected_gain_rule_says_what_the_next_batch_may_find_in_the_same_terms():
    """Issue 46: with ``stop_when_no_gain`` the line, the stop's reason, the rule as a lab
    pre-registers it and a schedule that never stopped speak of what the next batch may find,
    in the participant's terms."""
    config = study_config(**GAIN)
    state = SessionState(slots=protocol_slots(config), cursor=10)  # batch 2 opens: 1 is done
    line = learning_line(state, config, signal(42), None, [star(5, 3.0), star(10, 3.05)],
                         gain(0.35, config))
    assert line == (
        "After learning batch 1 of 4: the learner's best guess has not moved for 1 batch; the next "
        "batch is at most 35 % likely to find a handover the participant would pick over the "
        "learner's best guess more than 80 % of the time. Learning stops early once that is 20 % "
        "or less (from batch 1 on); until then it goes on, at most 3 more batches.")
    # the gain rule's line needs its own signal: the settled one alone says nothing
    assert learning_line(state, config, signal(42), None, [], None) is None
    reason = stop_reason(config, 1, 0.15)
    assert reason == ("after learning batch 1 of 4 the next batch was at most 15 % likely to find "
                      "a handover the participant would pick over the learner's best guess more "
                      "than 80 % of the time; it stops at 20 % or less, from batch 1 on")
    words = rule_words(config.stopping_rule())
    assert words == ("stop once the next batch is at most 20 % likely to find a handover the "
                     "participant would pick over the learner's best guess more than 80 % of the "
                     "time, from batch 1 on")
    assert rule_words(study_config(**STOPPING).stopping_rule()) == (
        "stop once 90 % sure that the learner's best guess is close to the participant's best (they "
        "would pick their very best handover over it at most 60 % of the time), from batch 2 on")
    never = never_stopped(config.stopping_rule())
    assert never == ("the fixed schedule: the next batch never became unlikely enough to find a "
                     "better handover (at most 20 %)")
    assert not JARGON.search(line + reason + words + never)

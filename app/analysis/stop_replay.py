"""A stopping rule tried on sessions already recorded (issue 46): where would it have stopped
learning, with which θ*, and how much would the participant have lost?

Each session stores the learner's exact state with every θ it planned (``learner_snapshots``), so
the learner as it stood after each batch is restored (:meth:`PreferenceLearner.restore`), its
stopping signals are computed again (how settled θ*, :mod:`app.learning.settled`; what the next
batch may gain, :mod:`app.learning.gain`) and any rule is applied to them: learning stops after the
first learning batch at which the rule stops, else at the end of the learning the session ran. Per
participant and rule: after which interaction it stops, θ* then and the session's final θ*, and
the final learner's predicted preference between them,

    P(final θ* ≻ θ* at the stop) = Φ(m / √(2 + s²)),

m and s² the posterior mean and variance of u(final) − u(stop) (the probit of eq. (13) integrated
over the posterior): 50 % when the stop lost nothing the learner can tell. A lab replays its pilot
with several ``chance`` values and picks the one that stops early at an acceptable preference.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import torch
from pydantic import BaseModel, ConfigDict, Field
from scipy.stats import norm

from app.learning.config import GainRule, LearnerSnapshot, StoppingRule
from app.learning.learner import PreferenceLearner
from app.learning.models import NextBatchGain, Settledness
from app.protocol.learning_words import rule_words
from app.protocol.study_config import StudyConfig
from session_store.paths import participant_codes
from session_store.read_only_copy import reading


class BatchSignals(BaseModel):
    """The learner after one batch of a stored session: its θ* and stopping signals."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    after_interaction: int
    batches: int = Field(description="learning batches done (0: the initial batch)")
    settled: Settledness | None
    gain: NextBatchGain | None
    theta_star: dict[str, float]


class ReplayedStop(BaseModel):
    """One participant under one rule."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    participant: str
    scenario: str
    rule: str
    stopped_after: int = Field(description="the last interaction learned from")
    learned: int = Field(description="the interactions the session itself learned from")
    signal: float | None = Field(description="the rule's signal where it stopped (None: it did "
                                 "not stop before the session's end)")
    theta_stop: dict[str, float]
    theta_final: dict[str, float]
    preferred_final: float = Field(description="P(final θ* ≻ θ* at the stop), the final learner's")


def batch_signals(config: StudyConfig, snapshots: Sequence[LearnerSnapshot],
                  after: Sequence[int]) -> list[BatchSignals]:
    """The signals after each batch of a session: the snapshots stored after the initial batch
    and after every learning batch (``after[i]`` the interactions snapshot ``i`` had learned)."""
    ends = {config.initial_trials + b * config.batch_size: b
            for b in range(config.learning_batches + 1)}
    found = []
    for snapshot, n in zip(snapshots, after, strict=True):
        if n not in ends:
            continue
        learner = PreferenceLearner.restore(snapshot)
        best = learner.best()
        if best is None:
            continue
        found.append(BatchSignals(after_interaction=n, batches=ends[n],
                                  settled=learner.settledness(), gain=learner.expected_gain(),
                                  theta_star=best.theta))
    return found


def preferred(learner: PreferenceLearner, first: dict[str, float],
              second: dict[str, float]) -> float:
    """P(``first`` ≻ ``second``) under ``learner``'s posterior: Φ(m/√(2 + s²))."""
    box = learner.config.box
    model = learner.model.model
    if model is None:
        return 0.5
    X = torch.tensor([box.to_unit(first), box.to_unit(second)], dtype=torch.float64)
    with torch.no_grad():
        posterior = model.posterior(X)
    mean = posterior.mean.reshape(2)
    cov = posterior.covariance_matrix.reshape(2, 2)
    m = float(mean[0] - mean[1])
    s2 = max(float(cov[0, 0] + cov[1, 1] - 2 * cov[0, 1]), 0.0)
    return float(norm.cdf(m / math.sqrt(2.0 + s2)))


def replay_participant(code: str, config: StudyConfig, snapshots: Sequence[LearnerSnapshot],
                       after: Sequence[int],
                       rules: Sequence[StoppingRule | GainRule]) -> list[ReplayedStop]:
    """Every rule on one stored session (its learner snapshots in order, ``after`` each one's
    interactions learned)."""
    if not snapshots:
        return []
    signals = batch_signals(config, snapshots, after)
    final = PreferenceLearner.restore(snapshots[-1])
    final_best = final.best()
    if final_best is None or not signals:
        return []
    rows = []
    for rule in rules:
        stop = next((s for s in signals[:-1] if _stops(rule, s)), None)
        theta = stop.theta_star if stop is not None else final_best.theta
        rows.append(ReplayedStop(
            participant=code, scenario=config.scenario.value, rule=rule_words(rule),
            stopped_after=stop.after_interaction if stop is not None else after[-1],
            learned=after[-1], signal=None if stop is None else _signal(rule, stop),
            theta_stop=theta, theta_final=final_best.theta,
            preferred_final=preferred(final, final_best.theta, theta)))
    return rows


def _stops(rule: StoppingRule | GainRule, signals: BatchSignals) -> bool:
    if isinstance(rule, GainRule):
        return rule.stops(signals.batches, signals.gain)
    return rule.stops(signals.batches, signals.settled)


def _signal(rule: StoppingRule | GainRule, signals: BatchSignals) -> float | None:
    if isinstance(rule, GainRule):
        return None if signals.gain is None else signals.gain.chance(rule.epsilon)
    return None if signals.settled is None else signals.settled.probability_within(rule.epsilon)


def replay_study(study_dir: Path, rules: Sequence[StoppingRule | GainRule]) -> list[ReplayedStop]:
    """Every rule on every participant of ``study_dir`` who has learner snapshots."""
    rows = []
    for code in participant_codes(study_dir):
        with reading(study_dir, code) as store:
            config = StudyConfig.model_validate(store.participant().config)
            stored = store.rows("learner_snapshots", order_by="after_interaction")
        snapshots = [LearnerSnapshot.model_validate_json(r.state) for r in stored]
        rows += replay_participant(code, config, snapshots, [r.after_interaction for r in stored],
                                   rules)
    return rows

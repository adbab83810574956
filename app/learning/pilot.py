"""``handover pilot``: simulate whole studies before recruiting anyone (planning the sample size).

One simulated study follows the paper's protocol (Sect. V-C) for ``participants`` simulated
participants in each of ``scenarios`` scenarios: 5 initial interactions, 4 learning batches of 5
(θ* + 4 queries), 1 interaction with the learned best, then 4 validation pairs, each the learned θ*
against a uniformly random θ in random order. The simulated participant is that of Sect. IV: an
optimum θ_t (per scenario a population, :func:`~app.learning.simulation.participant_target`),
utility u = ‖θ_t − θ‖ (15), each interaction observed as y = u + j·N(0, σ²) (16) with j its
position in the batch (in a validation pair j = 1, 2), and of two handovers the one with the
smaller y preferred. A participant's validation score is the share of pairs won by θ* (Tables
II–III); the study's test is the paper's sign test of the scores against 50 % (ties dropped,
one-sided), significant at α when p < α. Options beyond the paper: a participant who says "equal"
(``tie``) and a learner that models ties (``ties``); learning that ends once settled
(``stopping``, as ``[protocol] stop_when_settled``), validating the θ* of the batch it stopped at;
a participant who gives coactive hints (``coactive``, :mod:`app.learning.coactive`).

Over M studies: the distribution of validation scores, and the power (share of studies
significant) at α = 0.05 and 0.001 with Clopper–Pearson 95 % CIs, also for fewer participants per
scenario (the first n of each simulated study), which is the planning curve of the figure.
Participants are independent Dask tasks seeded by (seed, study, scenario, participant); results
go to ``participants.csv`` and resume from it.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Annotated

import numpy as np
from distributed import Client
from pydantic import BaseModel, ConfigDict, Field
from scipy import stats

from app.learning.cluster import run_tasks
from app.learning.config import DEFAULT_RECOMMENDATION, AcquisitionName, StoppingRule
from app.learning.errors import StudyError
from app.learning.models import RecommendationName, TieHandling
from app.learning.paper_population import PaperPopulation
from app.learning.planner import PAPER_SESSION_SCHEDULE, BatchSchedule
from app.learning.rng import derive_seed
from app.learning.simulated_study import append_durably
from app.learning.simulation import (
    StudyCondition,
    participant_target,
    simulate_learner,
    stop_point,
    stopped_theta_star,
)

PARTICIPANT_COLUMNS = ("study", "scenario", "participant", "wins", "pairs", "score",
                       "final_distance", "learning_interactions", "ties", "hints")
ALPHAS = (0.05, 0.001)


class PilotConfig(BaseModel):
    """One pilot: M studies of ``scenarios`` × ``participants`` simulated participants."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    studies: int = Field(50, ge=1, le=100_000, description="M, simulated studies")
    participants: int = Field(8, ge=1, le=1000, description="participants per scenario")
    scenarios: int = Field(2, ge=1, le=20, description="scenarios (paper: 2)")
    noise: float = Field(0.05, ge=0.0, le=1.0, description="σ of eq. (16)")
    spread: Annotated[float, Field(ge=0.0, le=1.0)] | PaperPopulation | None = Field(
        None, description="population spread of the optima in a scenario; None: uniform optima "
        "(no shared structure); 'paper': the θ* of Tables II–III resampled "
        "(app.learning.paper_population)")
    acquisition: AcquisitionName = AcquisitionName.QNEI
    recommendation: RecommendationName = DEFAULT_RECOMMENDATION
    schedule: BatchSchedule = PAPER_SESSION_SCHEDULE
    validation_pairs: int = Field(4, ge=1, le=50, description="θ* vs random pairs (paper: 4)")
    seed: int = Field(0, ge=0)
    dim: int = Field(3, ge=1, le=10)
    batch_position_noise: bool = Field(False, description="the learner weighs comparisons by the "
                                       "noise of eq. (16) (app.learning.comparison_noise)")
    tie: float = Field(0.0, ge=0.0, le=1.0, description="the participant says \"equal\" below "
                       "this difference of impressions (0: never)")
    ties: TieHandling = Field(TieHandling.DROP, description="the learner drops or models ties")
    stopping: StoppingRule | None = Field(None, description="end learning once settled "
                                          "(app.learning.settled); None: the fixed schedule")
    coactive: bool = Field(False, description="the participant gives coactive hints "
                           "(app.learning.coactive)")

    @property
    def condition(self) -> StudyCondition:
        return StudyCondition(acquisition=self.acquisition, q=self.schedule.q, noise=self.noise,
                              n_unique=self.schedule.n_unique, n_initial=self.schedule.n_initial,
                              dim=self.dim, recommendation=self.recommendation,
                              coactive=self.coactive).with_batch_position_noise(self.batch_position_noise
                                                          ).with_ties(self.tie, self.ties)


class ParticipantResult(BaseModel):
    """One simulated participant's validation: θ* won ``wins`` of ``pairs`` pairs."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    study: int
    scenario: int
    participant: int
    wins: int
    pairs: int
    final_distance: float = Field(description="u(θ*) at the end of learning")
    learning_interactions: int = Field(0, description="interactions learning used (0: not "
                                       "recorded, a pilot from before it was)")
    ties: int = Field(0, description="ties the learner used")
    hints: int = Field(0, description="coactive hints the participant gave")

    @property
    def score(self) -> float:
        return self.wins / self.pairs


def simulate_participant(config: PilotConfig, study: int, scenario: int,
                         participant: int) -> ParticipantResult:
    """Learning (schedule + the best interaction, which teaches nothing) then validation."""
    target = participant_target(config.dim, config.seed, study * config.scenarios + scenario,
                                participant, config.spread)
    key = (config.seed, study, scenario, participant)
    trial, _ = simulate_learner(config.condition, target, derive_seed(*key, 1),
                                derive_seed(*key, 2), derive_seed(*key, 4),
                                settle=config.stopping is not None)
    used = (len(trial.distances) if config.stopping is None
            else stop_point(trial, config.schedule, config.stopping))
    wins = validation_wins(target, np.array(stopped_theta_star(trial, used)),
                           config.validation_pairs, config.noise,
                           np.random.default_rng(derive_seed(*key, 3)))
    return ParticipantResult(study=study, scenario=scenario, participant=participant, wins=wins,
                             pairs=config.validation_pairs,
                             final_distance=trial.distances[used - 1],
                             learning_interactions=used, ties=trial.ties, hints=trial.hints)


def validation_wins(target: np.ndarray, theta_star: np.ndarray, pairs: int, noise: float,
                    rng: np.random.Generator) -> int:
    """Of ``pairs`` validation pairs (θ* against a uniformly random θ, in random order, Sect. V-C),
    how many the simulated participant with optimum ``target`` prefers θ* in: each handover felt
    as y = u + j·N(0, σ²) (16), j its position within the pair, the smaller y preferred."""
    wins = 0
    for _ in range(pairs):
        reference = rng.uniform(size=len(target))
        star_first = bool(rng.integers(2))
        u_star, u_ref = (float(np.linalg.norm(target - p)) for p in (theta_star, reference))
        j_star, j_ref = (1, 2) if star_first else (2, 1)
        y_star = u_star + j_star * rng.normal(0.0, noise)  # eq. (16), j within the pair
        y_ref = u_ref + j_ref * rng.normal(0.0, noise)
        wins += y_star < y_ref
    return wins


def sign_test_p(scores: list[float]) -> float:
    """One-sided sign test of validation scores against 50 % (ties dropped); 1.0 if all tie."""
    above = sum(s > 0.5 for s in scores)
    below = sum(s < 0.5 for s in scores)
    if above + below == 0:
        return 1.0
    return float(stats.binomtest(above, above + below, 0.5, alternative="greater").pvalue)


class PowerEstimate(BaseModel):
    """Share of the M studies whose sign test is significant at ``alpha``, with its 95 % CI."""

    model_config = ConfigDict(frozen=True)

    participants_per_scenario: int
    alpha: float
    significant: int
    studies: int
    power: float
    ci_low: float
    ci_high: float


class PilotReport(BaseModel):
    """What ``handover pilot --json`` prints."""

    model_config = ConfigDict(frozen=True)

    config: PilotConfig
    score_distribution: dict[str, float] = Field(description="share of participants per score")
    mean_score: float
    mean_final_distance: float
    median_learning_interactions: float = Field(description="interactions learning used")
    mean_hints: float = Field(0.0, description="coactive hints per participant")
    power: list[PowerEstimate] = Field(description="at the configured N, each α")
    power_curve: list[PowerEstimate] = Field(description="first n participants per scenario")
    out_dir: str
    figure: str | None = None


def power_at(results: list[ParticipantResult], studies: int, n: int,
             alpha: float) -> PowerEstimate:
    """Power of the sign test with the first ``n`` participants of every scenario."""
    significant = 0
    for study in range(studies):
        scores = [r.score for r in results if r.study == study and r.participant < n]
        significant += sign_test_p(scores) < alpha
    ci = stats.binomtest(significant, studies).proportion_ci(method="exact")
    return PowerEstimate(participants_per_scenario=n, alpha=alpha, significant=significant,
                         studies=studies, power=significant / studies, ci_low=float(ci.low),
                         ci_high=float(ci.high))


def report(config: PilotConfig, results: list[ParticipantResult], out: Path) -> PilotReport:
    """Scores, power at N and the power curve over n = 1 … N participants per scenario."""
    pairs = config.validation_pairs
    distribution = {f"{100 * w / pairs:g}%": sum(r.wins == w for r in results) / len(results)
                    for w in range(pairs + 1)}
    curve = [power_at(results, config.studies, n, alpha)
             for n in range(1, config.participants + 1) for alpha in ALPHAS]
    return PilotReport(
        config=config, score_distribution=distribution,
        mean_score=float(np.mean([r.score for r in results])),
        mean_final_distance=float(np.mean([r.final_distance for r in results])),
        median_learning_interactions=float(np.median([r.learning_interactions
                                                      for r in results])),
        mean_hints=float(np.mean([r.hints for r in results])),
        power=[p for p in curve if p.participants_per_scenario == config.participants],
        power_curve=curve, out_dir=str(out))


class PilotStore:
    """``participants.csv`` (one row per simulated participant) and ``pilot.json`` (settings)."""

    def __init__(self, out: Path, config: PilotConfig) -> None:
        self.path = out / "participants.csv"
        out.mkdir(parents=True, exist_ok=True)
        meta = out / "pilot.json"
        settings = config.model_dump(mode="json", exclude={"studies", "participants"})
        if meta.exists() and json.loads(meta.read_text()) != settings:
            raise StudyError(f"--out {out} holds a pilot with other settings "
                             f"({meta.read_text().strip()}); use another --out or the same settings")
        meta.write_text(json.dumps(settings, indent=2) + "\n")

    def load(self) -> dict[tuple[int, int, int], ParticipantResult]:
        if not self.path.exists():
            return {}
        with self.path.open(newline="") as handle:
            rows = [r for r in csv.DictReader(handle) if None not in r.values() and all(r.values())]
        results = [ParticipantResult(study=int(r["study"]), scenario=int(r["scenario"]),
                                     participant=int(r["participant"]), wins=int(r["wins"]),
                                     pairs=int(r["pairs"]),
                                     final_distance=float(r["final_distance"]),
                                     learning_interactions=int(r.get("learning_interactions") or 0),
                                     ties=int(r.get("ties") or 0),
                                     hints=int(r.get("hints") or 0)) for r in rows]
        return {(r.study, r.scenario, r.participant): r for r in results}

    def append(self, result: ParticipantResult) -> None:
        header = ",".join(PARTICIPANT_COLUMNS) + "\n" if not self.path.exists() else ""
        append_durably(self.path, header + _row(result))

    def rewrite(self, results: list[ParticipantResult]) -> None:
        tmp = self.path.with_suffix(".csv.tmp")
        tmp.write_text(",".join(PARTICIPANT_COLUMNS) + "\n" + "".join(map(_row, results)))
        tmp.replace(self.path)


def _row(r: ParticipantResult) -> str:
    return (f"{r.study},{r.scenario},{r.participant},{r.wins},{r.pairs},{r.score!r},"
            f"{r.final_distance!r},{r.learning_interactions},{r.ties},{r.hints}\n")


def run_pilot(config: PilotConfig, *, client: Client, out: Path,
              progress: bool = True) -> PilotReport:
    """Run (or resume) the pilot's M studies on ``client``; write ``participants.csv``."""
    store = PilotStore(out, config)
    keys = [(s, c, p) for s in range(config.studies) for c in range(config.scenarios)
            for p in range(config.participants)]
    done = store.load()  # a larger earlier pilot's extra rows are kept, not reported
    todo = [k for k in keys if k not in done]

    def finished(result: ParticipantResult) -> None:
        store.append(result)
        done[(result.study, result.scenario, result.participant)] = result

    run_tasks(client, simulate_participant, [(config, *k) for k in todo], finished,
              total=len(keys), initial=len(keys) - len(todo), desc="pilot", progress=progress)
    store.rewrite([done[k] for k in sorted(done)])
    return report(config, [done[k] for k in keys], out)

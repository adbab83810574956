"""The gain of a prior from earlier participants (app.learning.pooled_prior), measured honestly.

Populations of ``--group`` simulated participants share an optimum θ_0 ~ U[0, 1]³; each one's
optimum is θ_0 + N(0, spread²·I), clipped (``--spread``; ``--spread none``: uniform optima, no
shared structure; ``--spread paper``: the paper's participants, each optimum one of the θ* of Table
II (even populations) or III (odd) plus jitter, app.learning.paper_population). Every participant
runs once without a prior (these runs are also the earlier participants' data) and once with the
prior pooled from the *other* ``group − 1`` participants of its population, on the same optimum and
the same noise (paired). Reported over participants, with a cluster bootstrap over populations for
the 95 % CIs:

- ratio = mean u(θ*) with the prior at interaction ``--early`` / mean u(θ*) without it at the
  final interaction (≤ 1: the prior reaches at ``--early`` what none reaches at the end);
- final ratio = with / without at the final interaction (the cost where there is no structure).

θ* is recommended by ``--recommendation`` (default: the learner's default strategy).

Usage: ``nice -n 19 .venv/bin/python benchmarks/population_prior.py --spread 0.1 --populations 12
--workers 2 [--weight 0.3]``
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from app.learning.cluster import dask_client, run_tasks
from app.learning.config import DEFAULT_RECOMMENDATION, LearnerSnapshot
from app.learning.models import RecommendationName
from app.learning.paper_population import PAPER_POPULATION
from app.learning.pooled_prior import population_prior
from app.learning.rng import derive_seed
from app.learning.simulation import StudyCondition, participant_target, simulate_learner


def participant(condition: StudyCondition, seed: int, spread: float | None, population: int,
                index: int, prior_json: str | None) -> dict:
    """One run; ``prior_json``: the other participants' snapshots, or None for no prior."""
    from app.learning.prior import PopulationPrior

    target = participant_target(condition.dim, seed, population, index, spread)
    prior = None if prior_json is None else PopulationPrior.model_validate_json(prior_json)
    key = (seed, population, index)
    trial, learner = simulate_learner(condition, target, derive_seed(*key, 1),
                                      derive_seed(*key, 2), derive_seed(*key, 3), prior=prior,
                                      strategies=tuple(RecommendationName))
    return {"population": population, "index": index, "prior": prior is not None,
            "distances": trial.distances, "snapshot": learner.snapshot().model_dump_json(),
            "strategies": {s.value: curve for s, curve in trial.strategy_distances.items()}}


def load(path: Path) -> dict[tuple[int, int, bool], dict]:
    if not path.exists():
        return {}
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.endswith("}")]
    return {(r["population"], r["index"], r["prior"]): r for r in rows}


def oracle_curve(row: dict, target: np.ndarray) -> np.ndarray:
    """u of the best handover shown so far, after each interaction (the oracle curve), from the
    stored snapshot (the simulated box is the unit cube)."""
    snapshot = LearnerSnapshot.model_validate_json(row["snapshot"])
    shown = [[i.theta[name] for name in snapshot.config.box.names] for i in snapshot.interactions]
    return np.minimum.accumulate(np.linalg.norm(np.array(shown) - target, axis=1))


def cluster_bootstrap(num: np.ndarray, den: np.ndarray, seed: int) -> tuple[float, float]:
    """95 % CI of mean(num)/mean(den), resampling the rows (populations) with replacement."""
    rng = np.random.default_rng(seed)
    ratios = []
    for _ in range(4000):
        pick = rng.integers(len(num), size=len(num))
        ratios.append(num[pick].mean() / den[pick].mean())
    low, high = np.percentile(ratios, [2.5, 97.5])
    return float(low), float(high)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spread", default="0.1",
                        help="optimum spread, 'none' (uniform) or 'paper' (Tables II–III)")
    parser.add_argument("--populations", type=int, default=6)
    parser.add_argument("--group", type=int, default=9, help="participants per population")
    parser.add_argument("--noise", type=float, default=0.03)
    parser.add_argument("--weight", type=float, default=1.0, help="w of the prior mean")
    parser.add_argument("--early", type=int, default=15, help="interaction compared")
    parser.add_argument("--recommendation", default=DEFAULT_RECOMMENDATION.value,
                        choices=[r.value for r in RecommendationName],
                        help="how θ* is recommended (default: the learner's)")
    parser.add_argument("--batch-position-noise", action="store_true",
                        help="the likelihood weighs comparisons by the noise of eq. (16)")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--scheduler", default=None)
    parser.add_argument("--out", type=Path, default=Path("out/prior"))
    args = parser.parse_args()
    spread = (None if args.spread == "none" else args.spread if args.spread == PAPER_POPULATION
              else float(args.spread))
    condition = StudyCondition(noise=args.noise,
                               recommendation=RecommendationName(args.recommendation)
                               ).with_batch_position_noise(args.batch_position_noise)
    path = (args.out / f"spread-{args.spread}-s{args.noise:g}-w{args.weight:g}-"
            f"{args.recommendation}{'-bpn' if args.batch_position_noise else ''}.jsonl")
    path.parent.mkdir(parents=True, exist_ok=True)
    done = load(path)

    def keep(row: dict) -> None:
        with path.open("a") as handle:
            handle.write(json.dumps(row) + "\n")
        done[(row["population"], row["index"], row["prior"])] = row

    keys = [(p, i) for p in range(args.populations) for i in range(args.group)]
    with dask_client(args.scheduler, args.workers) as client:
        todo = [(condition, args.seed, spread, p, i, None) for p, i in keys
                if (p, i, False) not in done]
        run_tasks(client, participant, todo, keep, total=len(keys), desc="no prior")
        priors = []
        for p, i in keys:
            if (p, i, True) in done:
                continue
            others = {f"P{p}-{j}": LearnerSnapshot.model_validate_json(done[(p, j, False)]
                                                                       ["snapshot"])
                      for j in range(args.group) if j != i}
            prior = population_prior(others, weight=args.weight)
            priors.append((condition, args.seed, spread, p, i, prior.model_dump_json()))
        run_tasks(client, participant, priors, keep, total=len(keys), desc="with prior")

    def curves(prior: bool, strategy: str | None = None) -> np.ndarray:
        """u(θ*) per population × participant × interaction (``strategy``: one of the curves
        every strategy gets on the same runs; None: the run's own)."""
        return np.array([[done[(p, i, prior)]["distances"] if strategy is None
                          else done[(p, i, prior)]["strategies"][strategy]
                          for i in range(args.group)] for p in range(args.populations)])

    with_prior, without = curves(True), curves(False)
    n_final = without.shape[2]
    print(f"spread {args.spread}, σ = {args.noise:g}, w = {args.weight:g}, θ* by "
          f"{args.recommendation}: {args.populations} "
          f"populations × {args.group} participants (prior from the other {args.group - 1})")
    print(f"mean u(θ*): no prior at {args.early}: {without[..., args.early - 1].mean():.3f}, at "
          f"{n_final}: {without[..., -1].mean():.3f}; with prior at {args.early}: "
          f"{with_prior[..., args.early - 1].mean():.3f}, at {n_final}: "
          f"{with_prior[..., -1].mean():.3f}")
    targets = {(p, i): participant_target(condition.dim, args.seed, p, i, spread) for p, i in keys}
    for prior, label in ((False, "no prior"), (True, "with prior")):
        curve = np.mean([oracle_curve(done[(p, i, prior)], targets[(p, i)]) for p, i in keys], axis=0)
        print(f"oracle (best shown), {label}: "
              + ", ".join(f"at {n}: {curve[n - 1]:.3f}" for n in (1, 5, args.early, n_final)))
    report_ratios(with_prior, without, args.early, args.seed)
    curve = with_prior.mean(axis=(0, 1))
    reached = np.flatnonzero(curve <= without[..., -1].mean())
    print(f"with the prior, mean u(θ*) first reaches none@{n_final} ({without[..., -1].mean():.3f}) "
          f"at interaction {reached[0] + 1 if reached.size else 'never'}; with prior at 5/10/…: "
          + " ".join(f"{u:.3f}" for u in curve[4::5]))
    if all("strategies" in row for row in done.values()):
        for strategy in RecommendationName:
            print(f"θ* by {strategy.value} (the same runs):", end=" ")
            report_ratios(curves(True, strategy), curves(False, strategy), args.early, args.seed)


def report_ratios(with_prior: np.ndarray, without: np.ndarray, early: int, seed: int) -> None:
    """The ratio prior@early / none@final and the final ratio, with cluster-bootstrap CIs over
    populations (with one population, over its participants); arrays are population ×
    participant × interaction."""
    early_u, with_final, none_final = (with_prior[..., early - 1], with_prior[..., -1],
                                       without[..., -1])
    per_population = ((early_u.mean(1), none_final.mean(1), with_final.mean(1))
                      if len(early_u) > 1 else (early_u[0], none_final[0], with_final[0]))
    n_final = without.shape[2]
    low, high = cluster_bootstrap(per_population[0], per_population[1], seed)
    line = (f"ratio prior@{early} ({early_u.mean():.3f}) / none@{n_final} "
            f"({none_final.mean():.3f}): {early_u.mean() / none_final.mean():.2f} [{low:.2f}, "
            f"{high:.2f}]")
    low, high = cluster_bootstrap(per_population[2], per_population[1], seed)
    print(f"{line}\nfinal ratio prior / none at {n_final}: "
          f"{with_final.mean() / none_final.mean():.2f} [{low:.2f}, {high:.2f}]")


if __name__ == "__main__":
    main()

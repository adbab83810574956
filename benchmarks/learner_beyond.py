"""Beyond the paper's learner (issue 40): do stopping when settled, ties as information and coactive
hints pay?

Four studies with ``handover benchmark-pl``'s simulated participant (Sect. IV: utility ‖θ_t − θ‖ (15),
observed as y = u + j·N(0, σ²) (16)), the same participants (targets and noise seeded by the study
seed and the participant, so every arm is paired), on Dask like the other studies:

- **Stopping** (``[protocol] stop_when_settled``): each participant runs the fixed schedule once
  with the stopping signal recorded after every batch (app.learning.settled); the session that
  stops is a prefix of the full one, so the stopped and the fixed session are the same participant
  and the same noise. Printed per stopping rule: the learning interactions used (median,
  distribution) against the fixed schedule's, and the final distance u(θ*) of the stopped sessions
  over the fixed schedule's (ratio of means with a paired 95 % bootstrap interval). Goal: ≥ 30 %
  fewer interactions at a ratio whose upper bound is ≤ 1.05.
- **Ties** (``[learner] ties``): a participant who says "equal" when two impressions of a batch are
  closer than ``--tie``; the learner drops the ties (the paper) or models them (app.learning.ties).
  Printed: u(θ*) at 25 interactions (the session's schedule: 5 + 4 batches of 5), model over drop,
  with a paired 95 % bootstrap interval. Goal: ≤ 0.9.
- **Coactive hints** (app.learning.coactive): after each placement the participant may say which
  way δ or k (the 2nd, 3rd coordinate) should have gone; the session's schedule, ties dropped.
  Printed: the first interaction count n at which the mean u(θ*) with hints is at most the mean
  u(θ*) without hints at 25, with a paired bootstrap interval of n (participants resampled, both
  curves recomputed); goal: n ≤ 15 (the interval's upper bound). Also u(θ*) at 25 with hints over
  without, and the hints per participant.
- **All three together**: ties modelled and hints, learning stopped by the default rule, against
  the paper's fixed schedule (ties dropped, no hints, 25 interactions): interactions used and u(θ*).

And for every arm the validation score of Tables II–III: the share of 4 validation pairs (θ*
against a uniformly random θ, app.learning.pilot.validation_wins) the participant prefers θ* in,
the same pairs for every arm.

Tasks: ``sect4`` (the paper's Sect. IV: 5 + 5 batches of 5 = 30 interactions, no ties) for
stopping; ``session`` (the session's schedule, 25 interactions, with ties) for the others.

Resumable: one JSON line per participant and arm under ``--out``.

Usage: ``nice -n 10 .venv/bin/python benchmarks/learner_beyond.py --participants 200 --workers 2``
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np
from recommendation_study import ratio_ci
from scipy import stats

from app.learning.cluster import dask_client, run_tasks
from app.learning.config import StoppingRule, epsilon_for
from app.learning.models import TieHandling
from app.learning.paper_population import PaperPopulation
from app.learning.pilot import validation_wins
from app.learning.planner import PAPER_SESSION_SCHEDULE
from app.learning.rng import derive_seed
from app.learning.simulation import (
    StudyCondition,
    TrialResult,
    run_trial,
    stop_point,
    stopped_theta_star,
    trial_target,
)

#: The default rule first (90 % sure that the best θ would be preferred to θ* at most 60 % of the
#: time, after ≥ 2 batches), then looser ones down to one that stops at the first chance: the signal
#: is recorded as every posterior draw's regret, so any (threshold, preference) is evaluated offline.
RULES = tuple((pref, StoppingRule(threshold=p, min_batches=b, epsilon=epsilon_for(pref)))
              for p, b, pref in ((0.9, 2, 0.6), (0.8, 2, 0.65), (0.8, 1, 0.7), (0.8, 2, 0.9),
                                 (0.5, 1, 0.8)))
DEFAULT_RULE = RULES[0][1]
#: Hints must reach the no-hint arm's u(θ*) at 25 interactions by this many (issue 40).
COACTIVE_GOAL = 15
#: Validation pairs per participant (Tables II–III: 4).
VALIDATION_PAIRS = 4
BOOTSTRAP_RESAMPLES = 2000


def arms(noise: float, tie: float) -> dict[str, StudyCondition]:
    """The conditions run: Sect. IV's task, and the session's schedule with ties dropped/modelled,
    with hints (ties dropped), and with both (ties modelled and hints)."""
    session = StudyCondition(noise=noise, q=PAPER_SESSION_SCHEDULE.q,
                             n_unique=PAPER_SESSION_SCHEDULE.n_unique,
                             n_initial=PAPER_SESSION_SCHEDULE.n_initial)
    drop, model = session.with_ties(tie, TieHandling.DROP), session.with_ties(tie, TieHandling.MODEL)
    return {"session-drop": drop, "session-model": model,
            "session-coactive": drop.model_copy(update={"coactive": True}),
            "session-all": model.model_copy(update={"coactive": True}),
            "sect4": StudyCondition(noise=noise)}


def participant_arguments(parser: argparse.ArgumentParser, seed: int) -> None:
    """The simulated participants' options of this study and of learner_short.py: how many, the
    study seed, σ of eq. (16) and the "equal" threshold."""
    parser.add_argument("--participants", type=int, default=200)
    parser.add_argument("--seed", type=int, default=seed)
    parser.add_argument("--noise", type=float, default=0.05, help="σ of eq. (16)")
    parser.add_argument("--tie", type=float, default=0.05,
                        help="the participant says 'equal' below this difference of y")


def arm_path(out: Path, condition: StudyCondition, seed: int) -> Path:
    """Where an arm's results go: one JSON line per participant."""
    return out / f"{condition.name}-seed{seed}.jsonl"


def stored_results(path: Path) -> dict[int, TrialResult]:
    """The results already in ``path`` (none if it does not exist), by trial."""
    if not path.exists():
        return {}
    results = (TrialResult.model_validate_json(line) for line in path.read_text().splitlines()
               if line.strip())
    return {r.trial: r for r in results}


def append_result(path: Path, result: TrialResult) -> None:
    """Add one participant's result to ``path`` (a resumed run reads it back)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a") as handle:
        handle.write(result.model_dump_json() + "\n")


def run_arm(condition: StudyCondition, *, participants: int, seed: int, client, out: Path,
            progress: bool, spread: float | PaperPopulation | None = None) -> list[TrialResult]:
    """Run (or resume) ``participants`` trials of ``condition`` with the stopping signals
    (``spread``: the participants of a population, app.learning.simulation.trial_target)."""
    path = arm_path(out, condition, seed)
    done = stored_results(path)

    def finished(result: TrialResult) -> None:
        append_result(path, result)
        done[result.trial] = result

    todo = [(condition, seed, t, True, spread) for t in range(participants) if t not in done]
    run_tasks(client, run_trial, todo, finished, total=participants,
              initial=participants - len(todo), desc=condition.name, progress=progress)
    return [done[t] for t in range(participants)]


def stopped(condition: StudyCondition, results: list[TrialResult], rule: StoppingRule
            ) -> tuple[np.ndarray, np.ndarray]:
    """Per participant, the interactions learning used by ``rule`` and u(θ*) when it stopped."""
    used = np.array([stop_point(r, condition.schedule, rule) for r in results])
    return used, np.array([r.distances[n - 1] for r, n in zip(results, used, strict=True)])


def draw_tradeoff(tasks: dict[str, tuple[StudyCondition, list[TrialResult]]], path: Path) -> Path:
    """Mean interactions used against mean u(θ*) when learning stopped, one point per rule (the
    fixed schedule: the rule that never stops), per task."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6.4, 4.0))
    for task, (condition, results) in tasks.items():
        points = [stopped(condition, results, rule) for _, rule in RULES]
        fixed = np.mean([r.distances[-1] for r in results])
        curve = sorted((u.mean(), d.mean()) for u, d in points)
        line = axis.plot(*zip(*curve, strict=True), "o-", label=task)[0]
        axis.plot([condition.schedule.n_interactions], [fixed], "s", color=line.get_color(),
                  markersize=10, fillstyle="none")
        for (preference, rule), (u, d) in zip(RULES, points, strict=True):
            axis.annotate(f"{rule.threshold:.0%}/{preference:.0%}/{rule.min_batches}",
                          (u.mean(), d.mean()), fontsize=7, xytext=(4, 4),
                          textcoords="offset points")
    axis.set_xlabel("learning interactions used (mean)")
    axis.set_ylabel("u(θ*) when learning stopped (mean)")
    axis.set_title("Stopping when settled: interactions against distance (□ fixed schedule)",
                   fontsize=9)
    axis.legend(fontsize=8)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


def stopping_lines(task: str, condition: StudyCondition, results: list[TrialResult],
                   seed: int) -> list[str]:
    """One line per stopping rule: interactions used and final distance against the fixed."""
    fixed_n = condition.schedule.n_interactions
    fixed = np.array([r.distances[-1] for r in results])
    lines = []
    for preference, rule in RULES:
        used, stopped_at = stopped(condition, results, rule)
        saving, lo_s, hi_s = ratio_ci(used.astype(float), np.full(len(used), float(fixed_n)), seed)
        ratio, lo, hi = ratio_ci(stopped_at, fixed, seed)
        counts = ", ".join(f"{n}: {int((used == n).sum())}" for n in np.unique(used))
        goal = "met" if saving <= 0.7 and hi <= 1.05 else "not met"
        lines.append(
            f"stopping {task} {rule.threshold:.0%} sure best preferred ≤ {preference:.0%} after "
            f"≥{rule.min_batches} batches: "
            f"interactions median {np.median(used):g} of {fixed_n} (mean {used.mean():.1f}, "
            f"{1 - saving:.0%} fewer [{1 - hi_s:.0%}, {1 - lo_s:.0%}]; distribution {counts}); "
            f"final u(θ*) {stopped_at.mean():.3f} vs fixed {fixed.mean():.3f}, ratio {ratio:.3f} "
            f"[{lo:.3f}, {hi:.3f}]; goal (≥30 % fewer, ratio ≤ 1.05): {goal}")
    return lines


def ties_line(drop: list[TrialResult], model: list[TrialResult], seed: int, at: int) -> str:
    """u(θ*) at ``at`` interactions, ties modelled over dropped (paired bootstrap)."""
    a = np.array([r.distances[at - 1] for r in model])
    b = np.array([r.distances[at - 1] for r in drop])
    ratio, lo, hi = ratio_ci(a, b, seed)
    ties = np.array([r.ties for r in model])
    goal = "met" if hi <= 0.9 else "not met"
    return (f"ties at {at} interactions: u(θ*) model {a.mean():.3f} vs drop {b.mean():.3f}, "
            f"ratio {ratio:.3f} [{lo:.3f}, {hi:.3f}]; ties used per participant median "
            f"{np.median(ties):g} (mean {ties.mean():.1f}); goal (≤ 0.9): {goal}")


def reached_at(hinted: np.ndarray, plain: np.ndarray, at: int) -> np.ndarray:
    """Per resample (leading axes), the first interaction count n at which the mean u(θ*) of
    ``hinted`` (… × participants × interactions) is at most that of ``plain`` at ``at``; inf if
    never within the schedule."""
    level = plain[..., at - 1].mean(axis=-1, keepdims=True)
    below = hinted.mean(axis=-2) <= level
    return np.where(below.any(axis=-1), below.argmax(axis=-1) + 1.0, math.inf)


def coactive_line(plain: list[TrialResult], hinted: list[TrialResult], seed: int, at: int) -> str:
    """Interactions with hints to reach the no-hint u(θ*) at ``at`` (paired bootstrap of n), u(θ*)
    at ``at`` with over without hints, hints per participant."""
    a = np.array([r.distances for r in hinted])
    b = np.array([r.distances for r in plain])
    n = float(reached_at(a, b, at))
    resamples = np.random.default_rng(seed).integers(len(a), size=(BOOTSTRAP_RESAMPLES, len(a)))
    ns = reached_at(a[resamples], b[resamples], at)
    lo, hi = np.percentile(ns, 2.5, method="lower"), np.percentile(ns, 97.5, method="higher")
    ratio, r_lo, r_hi = ratio_ci(a[:, at - 1], b[:, at - 1], seed)
    hints = np.array([r.hints for r in hinted])
    goal = "met" if hi <= COACTIVE_GOAL else "not met"
    return (f"coactive hints: the no-hint u(θ*) at {at} ({b[:, at - 1].mean():.3f}) reached with "
            f"hints at n = {_count(n)} [{_count(lo)}, {_count(hi)}]; u(θ*) at {at} with "
            f"{a[:, at - 1].mean():.3f} vs without {b[:, at - 1].mean():.3f}, ratio {ratio:.3f} "
            f"[{r_lo:.3f}, {r_hi:.3f}]; hints per participant median {np.median(hints):g} (mean "
            f"{hints.mean():.1f}); goal (n ≤ {COACTIVE_GOAL}, upper bound): {goal}")


def _count(n: float) -> str:
    return f"{n:g}" if math.isfinite(n) else "never"


def together_line(condition: StudyCondition, together: list[TrialResult],
                  fixed: list[TrialResult], seed: int) -> str:
    """Ties modelled, hints and the default stopping rule against the paper's fixed schedule."""
    used, stopped_at = stopped(condition, together, DEFAULT_RULE)
    fixed_n = condition.schedule.n_interactions
    final = np.array([r.distances[-1] for r in fixed])
    saving, lo_s, hi_s = ratio_ci(used.astype(float), np.full(len(used), float(fixed_n)), seed)
    ratio, lo, hi = ratio_ci(stopped_at, final, seed)
    return (f"all three (ties modelled, hints, stopping {DEFAULT_RULE.threshold:.0%} sure after "
            f"≥{DEFAULT_RULE.min_batches} batches) vs the paper's fixed schedule: interactions "
            f"median {np.median(used):g} of {fixed_n} (mean {used.mean():.1f}, {1 - saving:.0%} "
            f"fewer [{1 - hi_s:.0%}, {1 - lo_s:.0%}]); final u(θ*) {stopped_at.mean():.3f} vs "
            f"{final.mean():.3f}, ratio {ratio:.3f} [{lo:.3f}, {hi:.3f}]")


def validation_scores(results: list[TrialResult], used: list[int], seed: int, noise: float,
                      spread: float | PaperPopulation | None = None) -> np.ndarray:
    """Per participant, the share of :data:`VALIDATION_PAIRS` pairs won by θ* when learning ended
    after ``used`` interactions; the same participant meets the same pairs in every arm."""
    scores = []
    for result, n in zip(results, used, strict=True):
        star = np.array(stopped_theta_star(result, n))
        target = trial_target(len(star), seed, result.trial, spread)
        rng = np.random.default_rng(derive_seed(seed, result.trial, 4))
        scores.append(validation_wins(target, star, VALIDATION_PAIRS, noise, rng) / VALIDATION_PAIRS)
    return np.array(scores)


def validation_line(arm: str, scores: np.ndarray, reference: np.ndarray, seed: int) -> str:
    """An arm's validation score (mean, bootstrap CI) and its ratio to the paper's arm (paired)."""
    ci = stats.bootstrap((scores,), np.mean, n_resamples=BOOTSTRAP_RESAMPLES, method="percentile",
                         random_state=np.random.default_rng(seed)).confidence_interval
    ratio, lo, hi = ratio_ci(scores, reference, seed)
    return (f"validation score {arm} (share of the {VALIDATION_PAIRS} pairs θ* vs random θ per "
            f"participant won by θ*, Tables II–III): {scores.mean():.3f} [{ci.low:.3f}, "
            f"{ci.high:.3f}]; over session-drop {ratio:.3f} [{lo:.3f}, {hi:.3f}]")


def validation_lines(conditions: dict[str, StudyCondition],
                     results: dict[str, list[TrialResult]], seed: int, noise: float) -> list[str]:
    """One line per arm (θ* after the fixed schedule), and the three together (stopped)."""
    missing = [name for name, rs in results.items() if any(not r.theta_star for r in rs)]
    if missing:
        return [f"validation scores: θ* is not recorded in the stored results of {missing} "
                "(written before TrialResult kept it); those arms must run again for them (another "
                "--out, or remove their .jsonl files)"]
    scores = {name: validation_scores(rs, [len(r.distances) for r in rs], seed, noise)
              for name, rs in results.items()}
    together, _ = stopped(conditions["session-all"], results["session-all"], DEFAULT_RULE)
    scores["session-all, stopped by the default rule"] = validation_scores(
        results["session-all"], list(together), seed, noise)
    return [validation_line(name, s, scores["session-drop"], seed) for name, s in scores.items()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    participant_arguments(parser, seed=4040)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--scheduler", default=None)
    parser.add_argument("--out", type=Path, default=Path("out/learner-beyond"))
    parser.add_argument("--figure", type=Path, default=None,
                        help="PNG of interactions against distance per rule (default OUT/stopping.png)")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args()

    conditions = arms(args.noise, args.tie)
    start = time.monotonic()
    with dask_client(args.scheduler, args.workers) as client:
        results = {name: run_arm(c, participants=args.participants, seed=args.seed,
                                 client=client, out=args.out, progress=not args.no_progress)
                   for name, c in conditions.items()}
    wall = time.monotonic() - start
    trials = [r for rs in results.values() for r in rs]
    print(f"N = {args.participants} paired participants (seed {args.seed}), σ = {args.noise:g}, "
          f"tie = {args.tie:g}; {np.mean([r.seconds for r in trials]):.1f} s per participant "
          f"and arm in a worker, {wall:.0f} s wall for this run")
    for line in stopping_lines("sect4", conditions["sect4"], results["sect4"], args.seed):
        print(line)
    for line in stopping_lines("session (ties dropped)", conditions["session-drop"],
                               results["session-drop"], args.seed):
        print(line)
    print(ties_line(results["session-drop"], results["session-model"], args.seed,
                    PAPER_SESSION_SCHEDULE.n_interactions))
    print(coactive_line(results["session-drop"], results["session-coactive"], args.seed,
                        PAPER_SESSION_SCHEDULE.n_interactions))
    print(together_line(conditions["session-all"], results["session-all"],
                        results["session-drop"], args.seed))
    for line in validation_lines(conditions, results, args.seed, args.noise):
        print(line)
    figure = draw_tradeoff({"sect4": (conditions["sect4"], results["sect4"]),
                            "session": (conditions["session-drop"], results["session-drop"])},
                           args.figure or args.out / "stopping.png")
    print(f"figure written to {figure}")
    print("baseline (the paper's fixed schedule, ties dropped): " + json.dumps(
        {name: round(float(np.mean([r.distances[-1] for r in rs])), 4)
         for name, rs in results.items()}))


if __name__ == "__main__":
    main()

"""Shorter sessions at the paper's quality (issue 46): hints and a stopping rule that fires.

Sect. IV's simulated participant (u = ‖θ_t − θ‖ (15), y = u + j·N(0, σ²) (16), "equal" within
0.05, ties dropped as the paper does) with the optima of the paper's own participants (Tables II
and III resampled, app.learning.paper_population: trial t is participant t // 2 of scenario
t mod 2), on the session's schedule (5 + 4 batches of 5 = 25 learning interactions), qNEI. The
arms are the same participants (targets and noise seeded by the study seed and the trial):

- ``paper``: the paper's protocol, no hints: the reference of every ratio;
- ``hints``: coactive hints (app.learning.coactive);
- ``hints-wrong``: 30 % of the hints point the opposite way;
- ``hints-faster``: "sooner" is read as "faster" half the time.

Every arm runs the whole schedule once with the stopping signals recorded after every batch (how
settled θ* is, app.learning.settled; what the next batch may gain, app.learning.gain); a session
that stops is a prefix of the whole one, so every rule is evaluated offline on the same runs.

Printed: every rule's interactions and u(θ*) when learning stopped, per arm and scenario (the
curve figure); the goals of issue 46 with paired 95 % bootstrap intervals (2,000 resamples):
(1) the short preset (hints and its rule) against the paper's arm: median learning interactions,
u(θ*) ratio, participant minutes from the time model below; (3) u(θ*) at 25 with wrong or
misread hints over the paper's arm; (5) the validation score (Tables II–III: 4 pairs, θ* against a
uniformly random θ, the same pairs in every arm) of the short sessions against the paper's.

Participant minutes (:class:`TimeModel`): a handover is the mean time from ``trial_started`` to
``trial_ended`` in the rehearsed sessions of ``--rehearsal`` (``handover run-session --rehearse
--auto``: the stand-in UR and the simulated hand on the wall clock); a scale placement, a hint, a
validation rating and a questionnaire answer are stated assumptions (the paper reports only "about
40 minutes" per participant for the whole procedure, briefing included).

Usage: ``nice -n 19 .venv/bin/python benchmarks/learner_short.py --participants 200 --workers 2
--rehearsal /tmp/rehearsal --figure docs/figures/learner-short-rules.png``
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable, Sequence
from datetime import datetime
from pathlib import Path

import numpy as np
from learner_beyond import (
    append_result,
    arm_path,
    participant_arguments,
    stored_results,
    validation_scores,
)
from pydantic import BaseModel, ConfigDict, Field
from recommendation_study import ratio_ci
from scipy import stats

from app.learning.cluster import dask_client, run_tasks
from app.learning.config import GainRule, StoppingRule, epsilon_for, preferred_for
from app.learning.models import TieHandling
from app.learning.paper_population import PAPER_POPULATION
from app.learning.planner import PAPER_SESSION_SCHEDULE
from app.learning.simulation import StudyCondition, TrialResult, run_trial, stop_point
from app.protocol.study_config import SHORT_RULE
from session_store.export import load_study

BOOTSTRAP_RESAMPLES = 2000
#: The paper's schedule: 5 + 4 batches of 5.
FULL = PAPER_SESSION_SCHEDULE.n_interactions

Rule = StoppingRule | GainRule | int  # an int: a fixed schedule of that many learning batches


def arms(noise: float, tie: float) -> dict[str, StudyCondition]:
    """The paper's protocol and the three hint arms, on the session's schedule, ties dropped."""
    paper = StudyCondition(noise=noise, q=PAPER_SESSION_SCHEDULE.q,
                           n_unique=PAPER_SESSION_SCHEDULE.n_unique,
                           n_initial=PAPER_SESSION_SCHEDULE.n_initial).with_ties(tie,
                                                                                TieHandling.DROP)
    hints = paper.model_copy(update={"coactive": True})
    return {"paper": paper, "hints": hints,
            "hints-wrong": hints.model_copy(update={"hint_flip": 0.3}),
            "hints-faster": hints.model_copy(update={"hint_faster": 0.5})}


def arm_trial(arm: str, condition: StudyCondition, seed: int, trial: int) -> tuple[str, TrialResult]:
    """One participant of one arm, with the stopping signals (a Dask task)."""
    return arm, run_trial(condition, seed, trial, True, PAPER_POPULATION)


def run_arms(conditions: dict[str, StudyCondition], *, participants: int, seed: int, client,
             out: Path, progress: bool) -> dict[str, list[TrialResult]]:
    """Run (or resume) every arm, participant by participant (all arms of participant t before
    any of t + 1), so that an interrupted run leaves every arm with the same participants."""
    paths = {arm: arm_path(out, c, seed) for arm, c in conditions.items()}
    done = {arm: stored_results(path) for arm, path in paths.items()}

    def finished(result: tuple[str, TrialResult]) -> None:
        arm, trial = result
        append_result(paths[arm], trial)
        done[arm][trial.trial] = trial

    todo = [(arm, c, seed, t) for t in range(participants) for arm, c in conditions.items()
            if t not in done[arm]]
    total = participants * len(conditions)
    run_tasks(client, arm_trial, todo, finished, total=total, initial=total - len(todo),
              desc="participants × arms", progress=progress)
    return {arm: [done[arm][t] for t in range(participants)] for arm in conditions}


def rule_families() -> dict[str, list[tuple[str, Rule]]]:
    """The rules drawn as curves: a fixed number of learning batches; the current rule (how sure
    that the best θ would be preferred to θ* at most p of the time), at 80 % sure, p from 60 to
    95 %; the expected gain of the next batch, at p = 60 % and 80 %, "unlikely" from 5 to 90 %."""
    fixed: list[tuple[str, Rule]] = [(f"{b} batches", b) for b in (1, 2, 3, 4)]
    settled: list[tuple[str, Rule]] = [
        (f"settled 80 %/{p:.0%}", StoppingRule(threshold=0.8, min_batches=1, epsilon=epsilon_for(p)))
        for p in (0.6, 0.7, 0.8, 0.9, 0.95)]
    gains: dict[float, list[tuple[str, Rule]]] = {
        p: [(f"gain {c:.0%}/{p:.0%}", GainRule(chance=c, preference=p, min_batches=1))
            for c in (0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9)] for p in (0.6, 0.8)}
    return {"fixed schedule": fixed, "settled (current rule)": settled,
            "gain, preferred > 60 %": gains[0.6], "gain, preferred > 80 %": gains[0.8]}


def used_by(rule: Rule, condition: StudyCondition, results: Sequence[TrialResult]) -> np.ndarray:
    """Per participant, the learning interactions ``rule`` lets learning use."""
    schedule = condition.schedule
    if isinstance(rule, int):
        n = schedule.n_initial + rule * schedule.q
        return np.array([min(n, len(r.distances)) for r in results])
    return np.array([stop_point(r, schedule, rule) for r in results])


def at_stop(results: Sequence[TrialResult], used: np.ndarray) -> np.ndarray:
    """u(θ*) when learning stopped."""
    return np.array([r.distances[n - 1] for r, n in zip(results, used, strict=True)])


class TimeModel(BaseModel):
    """Seconds per kind of step of a session; :meth:`minutes` of a session of a given length."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    handover_s: float = Field(description="trial_started → trial_ended, measured (rehearsal)")
    placement_s: float = Field(10.0, description="assumed: drag the new marker among up to four "
                               "earlier ones on the tablet's scale, then Confirm")
    hint_s: float = Field(5.0, description="assumed: read five choices, one tap, Confirm")
    rating_s: float = Field(5.0, description="assumed: better / worse / equal after a pair")
    answer_s: float = Field(15.0, description="assumed: read a question, answer on a 1-5 scale")

    def minutes(self, learning: np.ndarray, hinted: bool, best: int = 1, pairs: int = 4,
                questions: int = 3) -> np.ndarray:
        """A session's minutes: each learning interaction a handover, a placement and (hints) a
        hint screen; then the best handover, the questionnaire and the validation pairs."""
        per = self.handover_s + self.placement_s + (self.hint_s if hinted else 0.0)
        after = ((best + 2 * pairs) * self.handover_s + pairs * self.rating_s
                 + questions * self.answer_s)
        return (learning * per + after) / 60.0


def handover_seconds(study: Path) -> tuple[float, int]:
    """Mean seconds from ``trial_started`` to ``trial_ended`` of the completed trials of the
    sessions in ``study``, and how many trials that is."""
    events = load_study(study, ("events",)).tables["events"]
    started, durations = {}, []
    for _, row in events.iterrows():
        payload = json.loads(row["payload"])
        key = (row["participant"], payload.get("trial_index"))
        at = datetime.fromisoformat(str(row["at"])).timestamp()
        if row["kind"] == "trial_started":
            started[key] = at
        elif row["kind"] == "trial_ended" and payload["outcome"] == "completed" and key in started:
            durations.append(at - started[key])
    if not durations:
        raise SystemExit(f"--rehearsal {study}: no completed trial to time")
    return float(np.mean(durations)), len(durations)


def interval(statistic: Callable[..., float], *samples: np.ndarray, seed: int) -> tuple[float, float]:
    """Paired percentile-bootstrap 95 % interval of ``statistic`` over the participants."""
    ci = stats.bootstrap(samples, statistic, paired=True, vectorized=False,
                         n_resamples=BOOTSTRAP_RESAMPLES, method="percentile",
                         random_state=np.random.default_rng(seed)).confidence_interval
    return float(ci.low), float(ci.high)


#: The development grid (:func:`selection_lines`): both families at one learning batch before any
#: stop, from loose to strict.
SELECTION_GRID: tuple[StoppingRule | GainRule, ...] = (
    *(StoppingRule(threshold=t, min_batches=1, epsilon=epsilon_for(p))
      for t in (0.5, 0.6, 0.7, 0.8, 0.9) for p in (0.8, 0.85, 0.9, 0.93, 0.95, 0.97, 0.99)),
    *(GainRule(chance=c, preference=p, min_batches=1)
      for p in (0.6, 0.7, 0.8, 0.9, 0.95)
      for c in (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95)))
#: The development criterion: the largest saving of participant minutes among the rules whose
#: u(θ*) ratio to the paper's arm is at most this (a margin for the N = 200 interval's upper bound,
#: which must be ≤ 1.0) with a median of at most 15 learning interactions.
SELECTION_RATIO = 0.9


def rule_label(rule: Rule) -> str:
    """A rule in short words."""
    if isinstance(rule, int):
        return f"{rule} batches"
    if isinstance(rule, GainRule):
        return f"gain {rule.chance:.0%}/{rule.preference:.0%}/{rule.min_batches}"
    return f"settled {rule.threshold:.0%}/{preferred_for(rule.epsilon):.0%}/{rule.min_batches}"


def selection_lines(condition: StudyCondition, results: list[TrialResult],
                    reference: np.ndarray, times: TimeModel) -> list[str]:
    """Every rule of :data:`SELECTION_GRID` on the hints arm (the development study): mean and
    median interactions, u(θ*) over the paper arm's final, minutes saved; the rule the criterion
    picks last."""
    paper_minutes = times.minutes(np.full(len(results), float(FULL)), hinted=False).mean()
    rows = []
    for rule in SELECTION_GRID:
        used = used_by(rule, condition, results)
        ratio = at_stop(results, used).mean() / reference.mean()
        saved = 1 - times.minutes(used.astype(float), hinted=True).mean() / paper_minutes
        rows.append((saved, ratio, float(np.median(used)), used.mean(), rule))
    lines = [f"select {rule_label(rule):24s} n {mean:5.1f} (median {median:g}), u over paper's "
             f"final {ratio:.3f}, minutes {saved:.0%} fewer"
             for saved, ratio, median, mean, rule in sorted(rows, key=lambda r: r[3])]
    eligible = [r for r in rows if r[1] <= SELECTION_RATIO and r[2] <= 15]
    if eligible:
        saved, ratio, _, mean, rule = max(eligible, key=lambda r: (r[0], -r[1]))
        lines.append(f"selected: {rule_label(rule)} ({rule.model_dump()}): n {mean:.1f}, ratio "
                     f"{ratio:.3f}, minutes {saved:.0%} fewer")
    return lines


def rule_lines(name: str, condition: StudyCondition, results: list[TrialResult],
               reference: np.ndarray, scenarios: np.ndarray) -> list[str]:
    """Every rule on one arm: interactions used, share stopped early, u(θ*) at the stop, its
    ratio to the paper arm's final u(θ*), per scenario and both."""
    lines = []
    for family, rules in rule_families().items():
        for label, rule in rules:
            used = used_by(rule, condition, results)
            stop = at_stop(results, used)
            parts = []
            for scenario, keep in (("both", scenarios >= 0), ("II", scenarios == 0),
                                   ("III", scenarios == 1)):
                parts.append(f"{scenario}: n {used[keep].mean():.1f} (median "
                             f"{np.median(used[keep]):g}), u {stop[keep].mean():.3f}")
            lines.append(f"{name:13s} {family:24s} {label:18s} early {np.mean(used < FULL):4.0%}; "
                         + "; ".join(parts)
                         + f"; u over paper's final {stop.mean() / reference.mean():.3f}")
    return lines


def draw_curves(conditions: dict[str, StudyCondition], results: dict[str, list[TrialResult]],
                scenarios: np.ndarray, path: Path) -> Path:
    """Per scenario, every rule family's curve of mean learning interactions against mean u(θ*)
    when learning stopped, without hints (paper) and with them (hints)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(11, 4.4), sharey=True)
    styles = {"fixed schedule": ("s", ":"), "settled (current rule)": ("o", "--"),
              "gain, preferred > 60 %": ("^", "-"), "gain, preferred > 80 %": ("v", "-")}
    colours = {"paper": "tab:blue", "hints": "tab:orange"}
    for axis, (scenario, title) in zip(axes, ((0, "scenario 1, straightforward (Table II)"),
                                              (1, "scenario 2, perturbed (Table III)")),
                                       strict=True):
        keep = scenarios == scenario
        for arm, colour in colours.items():
            subset = [r for r, k in zip(results[arm], keep, strict=True) if k]
            for family, rules in rule_families().items():
                points = sorted((used_by(rule, conditions[arm], subset).mean(),
                                 at_stop(subset, used_by(rule, conditions[arm], subset)).mean())
                                for _, rule in rules)
                marker, line = styles[family]
                axis.plot(*zip(*points, strict=True), marker=marker, linestyle=line,
                          color=colour, markersize=4, linewidth=1,
                          label=f"{'no hints' if arm == 'paper' else 'hints'}: {family}")
        hinted = [r for r, k in zip(results["hints"], keep, strict=True) if k]
        short = used_by(SHORT_RULE, conditions["hints"], hinted)
        axis.plot([short.mean()], [at_stop(hinted, short).mean()], "*", color="black",
                  markersize=12, label="the short preset (hints, its rule)")
        paper_final = np.mean([r.distances[-1] for r, k in zip(results["paper"], keep,
                                                                strict=True) if k])
        axis.axhline(paper_final, color="grey", linewidth=0.8)
        axis.set_title(f"{title}, N = {int(keep.sum())}", fontsize=9)
        axis.set_xlabel("learning interactions used (mean)")
    axes[0].set_ylabel("u(θ*) when learning stopped (mean)")
    axes[1].legend(fontsize=6, loc="upper right")
    figure.suptitle("Stopping rules: interactions against distance (grey: the paper's protocol "
                    "after 25; ★: the short preset)", fontsize=9)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


#: Goal 2's rules: the current rule at its default and at the preset's settings, and the expected
#: gain at the issue's example ("unlikely", read as 20 %, to find a handover preferred to θ* more than
#: 60 % of the time) and at the development study's best gain rule.
GOAL2_RULES: tuple[StoppingRule | GainRule, ...] = (
    StoppingRule(), SHORT_RULE, GainRule(chance=0.2, preference=0.6, min_batches=1),
    GainRule(chance=0.8, preference=0.9, min_batches=1))


def firing_lines(conditions: dict[str, StudyCondition], results: dict[str, list[TrialResult]],
                 reference: np.ndarray, seed: int) -> list[str]:
    """Goal 2: how often each rule of :data:`GOAL2_RULES` stops learning early (Clopper–Pearson
    95 % interval), with and without hints, and u(θ*) when it stopped over the paper arm's."""
    lines = []
    for arm in ("paper", "hints"):
        for rule in GOAL2_RULES:
            used = used_by(rule, conditions[arm], results[arm])
            early = int((used < FULL).sum())
            ci = stats.binomtest(early, len(used)).proportion_ci(method="exact")
            ratio, lo, hi = ratio_ci(at_stop(results[arm], used), reference, seed)
            lines.append(f"goal 2, {arm}, {rule_label(rule)}: stops early for {early} of "
                         f"{len(used)} ({early / len(used):.0%} [{ci.low:.0%}, {ci.high:.0%}]), "
                         f"mean {used.mean():.1f} learning interactions, u(θ*) over the paper's "
                         f"final {ratio:.3f} [{lo:.3f}, {hi:.3f}]")
    return lines


def goal_lines(conditions: dict[str, StudyCondition], results: dict[str, list[TrialResult]],
               times: TimeModel, seed: int, noise: float) -> list[str]:
    """Goals 1, 2, 3 and 5 of issue 46 with their intervals."""
    paper = results["paper"]
    reference = np.array([r.distances[-1] for r in paper])
    rule = SHORT_RULE
    short_used = used_by(rule, conditions["hints"], results["hints"])
    short = at_stop(results["hints"], short_used)
    ratio, lo, hi = ratio_ci(short, reference, seed)
    median_lo, median_hi = interval(np.median, short_used.astype(float), seed=seed)
    counts = ", ".join(f"{n}: {int((short_used == n).sum())}" for n in np.unique(short_used))
    lines = [f"goal 1, the short preset (hints, {rule.model_dump()}): learning interactions "
             f"median {np.median(short_used):g} [{median_lo:g}, {median_hi:g}] (mean "
             f"{short_used.mean():.1f}; {counts}); u(θ*) {short.mean():.3f} vs the paper's "
             f"{reference.mean():.3f} after 25, ratio {ratio:.3f} [{lo:.3f}, {hi:.3f}]; goal "
             f"(median ≤ 15, upper bound ≤ 1.0): "
             f"{'met' if np.median(short_used) <= 15 and hi <= 1.0 else 'not met'}"]
    paper_minutes = times.minutes(np.full(len(paper), float(FULL)), hinted=False)
    for label, model in (("", times),
                         (" (hint as long as a placement)",
                          times.model_copy(update={"hint_s": times.placement_s}))):
        short_minutes = model.minutes(short_used.astype(float), hinted=True)
        m_ratio, m_lo, m_hi = ratio_ci(short_minutes, paper_minutes, seed)
        lines.append(f"goal 1, participant minutes{label}: short {short_minutes.mean():.1f} vs "
                     f"paper {paper_minutes.mean():.1f}, {1 - m_ratio:.0%} fewer "
                     f"[{1 - m_hi:.0%}, {1 - m_lo:.0%}]; goal (≥ 30 % fewer): "
                     f"{'met' if m_ratio <= 0.7 else 'not met'}")
    lines.append(f"time model: {times.model_dump()}")
    lines += firing_lines(conditions, results, reference, seed)
    for arm in ("hints", "hints-wrong", "hints-faster"):
        at25 = np.array([r.distances[-1] for r in results[arm]])
        ratio, lo, hi = ratio_ci(at25, reference, seed)
        hints = np.mean([r.hints for r in results[arm]])
        lines.append(f"goal 3, {arm} at 25: u(θ*) {at25.mean():.3f} vs no hints "
                     f"{reference.mean():.3f}, ratio {ratio:.3f} [{lo:.3f}, {hi:.3f}] ({hints:.1f} "
                     f"hints per participant); goal (≤ 1.05): {'met' if hi <= 1.05 else 'not met'}")
        used = used_by(rule, conditions[arm], results[arm])
        stopped = at_stop(results[arm], used)
        ratio, lo, hi = ratio_ci(stopped, reference, seed)
        lines.append(f"  {arm} with the short preset's rule: median {np.median(used):g} (mean "
                     f"{used.mean():.1f}), u(θ*) ratio {ratio:.3f} [{lo:.3f}, {hi:.3f}]")
    full = validation_scores(paper, [FULL] * len(paper), seed, noise, PAPER_POPULATION)
    cut = validation_scores(results["hints"], list(short_used), seed, noise, PAPER_POPULATION)
    ci_full, ci_cut = (interval(np.mean, s, seed=seed) for s in (full, cut))
    lines.append(f"goal 5, validation score (Tables II–III): short {cut.mean():.3f} "
                 f"[{ci_cut[0]:.3f}, {ci_cut[1]:.3f}] vs paper {full.mean():.3f} [{ci_full[0]:.3f}, "
                 f"{ci_full[1]:.3f}]; goal (overlaps or above): "
                 f"{'met' if ci_cut[1] >= ci_full[0] else 'not met'}")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    participant_arguments(parser, seed=4646)
    parser.add_argument("--arms", nargs="+", default=None, help="run only these arms")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--scheduler", default=None)
    parser.add_argument("--out", type=Path, default=Path("out/learner-short"))
    parser.add_argument("--rehearsal", type=Path, default=None,
                        help="a study folder of rehearsed sessions: the handover's time")
    parser.add_argument("--figure", type=Path, default=None,
                        help="PNG of the rules' curves (default OUT/rules.png)")
    parser.add_argument("--select", action="store_true",
                        help="print the development grid of rules and the one the criterion picks")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args()

    conditions = {name: c for name, c in arms(args.noise, args.tie).items()
                  if args.arms is None or name in args.arms}
    start = time.monotonic()
    with dask_client(args.scheduler, args.workers) as client:
        results = run_arms(conditions, participants=args.participants, seed=args.seed,
                           client=client, out=args.out, progress=not args.no_progress)
    wall = time.monotonic() - start
    trials = [r for rs in results.values() for r in rs]
    scenarios = np.arange(args.participants) % 2
    print(f"N = {args.participants} paired participants (seed {args.seed}; scenarios alternate, "
          f"Tables II and III), σ = {args.noise:g}, tie = {args.tie:g}; "
          f"{np.mean([r.seconds for r in trials]):.1f} s per participant and arm in a worker, "
          f"{wall:.0f} s wall for this run")
    reference = np.array([r.distances[-1] for r in results["paper"]])
    for name, condition in conditions.items():
        for line in rule_lines(name, condition, results[name], reference, scenarios):
            print(line)
    if "hints" in results:
        figure = draw_curves(conditions, results, scenarios,
                             args.figure or args.out / "rules.png")
        print(f"figure written to {figure}")
    if args.rehearsal is not None:
        seconds, count = handover_seconds(args.rehearsal)
        times = TimeModel(handover_s=seconds)
        print(f"a handover: {seconds:.2f} s (mean of {count} rehearsed trials in {args.rehearsal})")
        if args.select and "hints" in results:
            for line in selection_lines(conditions["hints"], results["hints"], reference, times):
                print(line)
        if set(results) == set(arms(args.noise, args.tie)):
            for line in goal_lines(conditions, results, times, args.seed, args.noise):
                print(line)
    print("baseline (the paper's protocol, u(θ*) after 25): "
          f"{reference.mean():.4f}" + ("" if math.isfinite(reference.mean()) else " (none)"))


if __name__ == "__main__":
    main()

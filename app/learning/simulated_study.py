"""Running the simulated study (Sect. IV): many trials per condition, on Dask, resumable.

Files in ``<out>/<condition name>/``:

- ``condition.json``: the condition and the study seed. Resuming with a different condition or seed
  is an error, so raw rows of different studies are never mixed.
- ``trials.csv``: raw rows, one per (trial, interaction): the inference distance u(θ*) of the
  condition's recommendation strategy (``distance``), the distance of the point shown, the oracle
  distance (best point shown so far), the inference distance of every strategy
  (``distance_<strategy>``), the fit failures of the trial and the coactive hints its participant
  gave. A trial's rows are appended in one
  ``write`` and flushed to disk when the trial is done; on resume, completed trials are read back
  and skipped, a partial trial (killed mid-write) is discarded and rerun. At the end the file is
  rewritten in trial order, so it is the same file whatever the workers and the order they
  finished in.
- ``timings.csv``: seconds per trial (machine-dependent, hence apart from the results).
- ``summary.csv``: per interaction, over the trials: mean distance with its 95 % confidence interval
  (Student t) and success rate (u(θ*) < 0.1), and the mean oracle distance.

Trials are seeded per (study seed, trial index) and run on Dask (:mod:`app.learning.cluster`), so
results do not depend on the number of workers or where they run.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import math
import os
import statistics
import time
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

from distributed import Client
from pydantic import BaseModel, ConfigDict
from scipy import stats

from app.learning.cluster import run_tasks
from app.learning.errors import StudyError
from app.learning.models import RecommendationName
from app.learning.simulation import SUCCESS_DISTANCE, StudyCondition, TrialResult, run_trial

logger = logging.getLogger(__name__)

STRATEGY_COLUMNS = tuple(f"distance_{s.value}" for s in RecommendationName)
TRIAL_COLUMNS = ("trial", "interaction", "distance", "shown_distance", "oracle_distance",
                 *STRATEGY_COLUMNS, "fit_failures", "hints")
TIMING_COLUMNS = ("trial", "seconds")
SUMMARY_COLUMNS = ("interaction", "n_trials", "mean_distance", "ci_low", "ci_high", "success_rate",
                   "mean_oracle_distance")


class InteractionSummary(BaseModel):
    """Statistics over trials at one interaction (1-based, as on the x-axis of Fig. 3)."""

    model_config = ConfigDict(frozen=True)

    interaction: int
    n_trials: int
    mean_distance: float
    ci_low: float
    ci_high: float
    success_rate: float
    mean_oracle_distance: float


class ConditionSummary(BaseModel):
    """What ``handover benchmark-pl --json`` prints for one condition.

    ``seconds_per_trial`` is the mean time one trial takes in its (single-threaded) worker,
    ``wall_seconds_per_trial`` this run's elapsed time divided by the trials it ran (lower with
    more workers; None when every trial was resumed from disk). ``final_strategy_distances``: the
    final mean inference distance of every recommendation strategy, ``final_oracle_distance`` the
    final mean distance of the best point shown, ``hints_per_trial`` the mean coactive hints.
    """

    model_config = ConfigDict(frozen=True)

    condition: str
    acquisition: str
    q: int
    noise: float
    trials: int
    interactions: int
    final_mean_distance: float
    final_ci: tuple[float, float]
    final_success_rate: float
    final_strategy_distances: dict[str, float]
    final_oracle_distance: float
    seconds_per_trial: float
    wall_seconds_per_trial: float | None
    fit_failures: int
    hints_per_trial: float
    out_dir: str


def t_half_width(values: Sequence[float]) -> float:
    """Half-width of the Student-t 95 % CI of the mean of ``values`` (NaN for fewer than two)."""
    n = len(values)
    return (float(stats.t.ppf(0.975, n - 1)) * statistics.stdev(values) / math.sqrt(n)
            if n > 1 else math.nan)


def summarise(results: list[TrialResult]) -> list[InteractionSummary]:
    """Mean distance of θ* to the target with 95 % CI, success rate and mean oracle distance, per
    interaction."""
    rows = []
    oracle = [statistics.fmean(v) for v in zip(*(r.oracle_distances for r in results),
                                                   strict=True)]
    for i, values in enumerate(zip(*(r.distances for r in results), strict=True)):
        n = len(values)
        mean = statistics.fmean(values)
        half = t_half_width(values)
        rows.append(InteractionSummary(
            interaction=i + 1, n_trials=n, mean_distance=mean, ci_low=mean - half,
            ci_high=mean + half,
            success_rate=sum(v < SUCCESS_DISTANCE for v in values) / n,
            mean_oracle_distance=oracle[i]))
    return rows


class TrialStore:
    """The raw ``trials.csv`` of one condition: atomic per-trial appends, resume."""

    def __init__(self, directory: Path, condition: StudyCondition, seed: int) -> None:
        self.directory = directory
        self.path = directory / "trials.csv"
        self.timings = directory / "timings.csv"
        self.n_interactions = condition.schedule.n_interactions
        directory.mkdir(parents=True, exist_ok=True)
        meta = {"condition": condition.model_dump(mode="json"), "seed": seed}
        meta_path = directory / "condition.json"
        if meta_path.exists():
            stored = json.loads(meta_path.read_text())
            if stored != meta:
                raise StudyError(
                    f"--out {directory} holds a study with seed = {stored.get('seed')} and "
                    f"condition {stored.get('condition')}; this run has seed = {seed} and "
                    f"{meta['condition']}: use another --out or the same settings to resume")
        else:
            meta_path.write_text(json.dumps(meta, indent=2) + "\n")

    def load(self) -> dict[int, TrialResult]:
        """Completed trials already on disk; rewrites the file without a partial trial, if any."""
        if not self.path.exists():
            return {}
        results = read_trials(self.directory, self.n_interactions)
        self.rewrite(results)
        return results

    def append(self, result: TrialResult) -> None:
        """Append one trial's rows with a single ``write`` and flush them to disk."""
        append_durably(self.path, _rows_text(result, header=_empty(self.path)))
        append_durably(self.timings, _timing_text(result, header=_empty(self.timings)))

    def rewrite(self, results: dict[int, TrialResult]) -> None:
        """Replace the file by ``results`` in trial order (atomically)."""
        tmp = self.path.with_suffix(".csv.tmp")
        text = "".join(_rows_text(results[t], header=i == 0) for i, t in enumerate(sorted(results)))
        tmp.write_text(text or _rows_text(None, header=True))
        os.replace(tmp, self.path)

def _empty(path: Path) -> bool:
    return not path.exists() or path.stat().st_size == 0


def read_trials(directory: Path, n_interactions: int) -> dict[int, TrialResult]:
    """The completed trials of a condition folder (read only): ``trials.csv`` rows grouped by
    trial, a trial with fewer than ``n_interactions`` rows (cut short by a kill) left out, and
    each trial's seconds from ``timings.csv`` (NaN where none was recorded)."""
    path = directory / "trials.csv"
    if not path.exists():
        return {}
    rows: dict[int, list[dict[str, str]]] = defaultdict(list)
    with path.open(newline="") as handle:
        for row in csv.DictReader(handle):
            if None in row.values() or None in row:
                continue  # a line cut short by an interruption
            rows[int(row["trial"])].append(row)
    complete = {t: r for t, r in rows.items() if len(r) == n_interactions}
    if len(complete) != len(rows):
        logger.warning("%s: discarding %d partial trial(s)", path, len(rows) - len(complete))
    seconds = _seconds(directory / "timings.csv")
    return {t: _result_from_rows(t, r, seconds.get(t, math.nan)) for t, r in complete.items()}


def _seconds(path: Path) -> dict[int, float]:
    if not path.exists():
        return {}
    with path.open(newline="") as handle:
        return {int(r["trial"]): float(r["seconds"]) for r in csv.DictReader(handle)
                if None not in r.values() and r["seconds"]}


def append_durably(path: Path, text: str) -> None:
    """Append ``text`` with a single ``write`` and flush it to disk (a kill leaves whole lines or
    one torn last line)."""
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        os.write(fd, text.encode())
        os.fsync(fd)
    finally:
        os.close(fd)


def _timing_text(result: TrialResult, header: bool) -> str:
    return (",".join(TIMING_COLUMNS) + "\n" if header else "") + \
        f"{result.trial},{result.seconds:.4f}\n"


def _rows_text(result: TrialResult | None, header: bool) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    if header:
        writer.writerow(TRIAL_COLUMNS)
    if result is not None:
        curves = [result.strategy_distances[s] for s in RecommendationName]
        rows = zip(result.distances, result.shown_distances, result.oracle_distances, *curves,
                   strict=True)
        for i, (d, s, o, *by_strategy) in enumerate(rows):
            writer.writerow((result.trial, i + 1, repr(d), repr(s), repr(float(o)),
                             *map(repr, by_strategy), result.fit_failures, result.hints))
    return buffer.getvalue()


def _result_from_rows(trial: int, rows: list[dict[str, str]], seconds: float) -> TrialResult:
    rows = sorted(rows, key=lambda r: int(r["interaction"]))
    curves = {s: [float(r[f"distance_{s.value}"]) for r in rows] for s in RecommendationName}
    return TrialResult(trial=trial, distances=[float(r["distance"]) for r in rows],
                       shown_distances=[float(r["shown_distance"]) for r in rows],
                       strategy_distances=curves, fit_failures=int(rows[0]["fit_failures"]),
                       hints=int(rows[0].get("hints") or 0), seconds=seconds)


def write_summary(path: Path, rows: list[InteractionSummary]) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(row.model_dump() for row in rows)


def condition_summary(condition: StudyCondition, results: list[TrialResult],
                      rows: list[InteractionSummary], directory: Path, seconds: list[float],
                      wall_seconds_per_trial: float | None) -> ConditionSummary:
    """The final figures of one condition: ``results`` in trial order and their ``rows``
    (:func:`summarise`); ``seconds`` per trial (NaN where unknown) for ``seconds_per_trial``."""
    timed = [s for s in seconds if not math.isnan(s)]
    final = rows[-1]
    return ConditionSummary(
        condition=condition.name, acquisition=condition.acquisition.value, q=condition.q,
        noise=condition.noise, trials=len(results), interactions=len(rows),
        final_mean_distance=final.mean_distance, final_ci=(final.ci_low, final.ci_high),
        final_success_rate=final.success_rate,
        final_strategy_distances={s.value: statistics.fmean(r.strategy_distances[s][-1]
                                                            for r in results)
                                  for s in RecommendationName},
        final_oracle_distance=final.mean_oracle_distance,
        seconds_per_trial=statistics.fmean(timed) if timed else math.nan,
        wall_seconds_per_trial=wall_seconds_per_trial,
        fit_failures=sum(r.fit_failures for r in results),
        hints_per_trial=statistics.fmean(r.hints for r in results), out_dir=str(directory))


def run_condition(condition: StudyCondition, *, trials: int, seed: int, client: Client,
                  out: Path, progress: bool = True
                  ) -> tuple[ConditionSummary, list[InteractionSummary]]:
    """Run (or resume) ``trials`` trials of ``condition`` on ``client``'s cluster and write its CSV
    files under ``out``."""
    directory = out / condition.name
    store = TrialStore(directory, condition, seed)
    stored = store.load()  # a larger earlier run's extra trials stay in the file, unreported
    results = {t: r for t, r in stored.items() if t < trials}
    todo = [t for t in range(trials) if t not in results]
    if results:
        logger.info("%s: resuming, %d of %d trials already done", condition.name, len(results),
                    trials)
    fresh: list[TrialResult] = []
    start = time.monotonic()

    def done(result: TrialResult) -> None:
        store.append(result)
        results[result.trial] = stored[result.trial] = result
        fresh.append(result)

    run_tasks(client, run_trial, [(condition, seed, t) for t in todo], done, total=trials,
              initial=len(results), desc=condition.name, progress=progress)
    wall = time.monotonic() - start
    store.rewrite(stored)
    ordered = [results[t] for t in sorted(results)]
    rows = summarise(ordered)
    write_summary(directory / "summary.csv", rows)
    timed = [r.seconds for r in fresh or ordered]
    summary = condition_summary(condition, ordered, rows, directory, timed,
                                wall / len(fresh) if fresh else None)
    return summary, rows


def final_distances(condition: StudyCondition, *, trials: int, seed: int, client: Client,
                    out: Path) -> list[float]:
    """Run (or resume) ``condition``; each trial's final inference distance u(θ*), in trial order
    (paired with any other condition of the same ``seed``: the same targets and noise)."""
    run_condition(condition, trials=trials, seed=seed, client=client, out=out, progress=False)
    stored = TrialStore(out / condition.name, condition, seed).load()
    return [stored[t].distances[-1] for t in range(trials)]

"""Running the simulated study (Sect. IV): many trials per condition, in parallel, resumable.

Files in ``<out>/<condition name>/``:

- ``condition.json``: the condition and the study seed. Resuming with a different condition or seed
  is an error, so raw rows of different studies are never mixed.
- ``trials.csv``: raw rows, one per (trial, interaction): the distance u(θ*) of the best point,
  the distance of the point shown, fit failures and seconds of the trial. A trial's rows are
  appended in one ``write`` and flushed to disk when the trial is done; on resume, completed trials
  are read back and skipped, a partial trial (killed mid-write) is discarded and rerun.
- ``summary.csv``: per interaction, over the trials: mean distance with its 95 % confidence interval
  (Student t) and success rate (u(θ*) < 0.1).

Trials are seeded per (study seed, trial index), so results do not depend on ``jobs``.
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
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

from pydantic import BaseModel, ConfigDict
from scipy import stats
from tqdm import tqdm

from app.learning.errors import StudyError
from app.learning.simulation import SUCCESS_DISTANCE, StudyCondition, TrialResult, run_trial

logger = logging.getLogger(__name__)

TRIAL_COLUMNS = ("trial", "interaction", "distance", "shown_distance", "fit_failures", "seconds")
SUMMARY_COLUMNS = ("interaction", "n_trials", "mean_distance", "ci_low", "ci_high", "success_rate")


class InteractionSummary(BaseModel):
    """Statistics over trials at one interaction (1-based, as on the x-axis of Fig. 3)."""

    model_config = ConfigDict(frozen=True)

    interaction: int
    n_trials: int
    mean_distance: float
    ci_low: float
    ci_high: float
    success_rate: float


class ConditionSummary(BaseModel):
    """What ``handover benchmark-pl --json`` prints for one condition.

    ``seconds_per_trial`` is the mean time one trial takes in its (single-threaded) process,
    ``wall_seconds_per_trial`` this run's elapsed time divided by the trials it ran (lower with
    ``--jobs`` > 1; None when every trial was resumed from disk).
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
    seconds_per_trial: float
    wall_seconds_per_trial: float | None
    fit_failures: int
    out_dir: str


def summarise(results: list[TrialResult]) -> list[InteractionSummary]:
    """Mean distance of θ* to the target with 95 % CI, and success rate, per interaction."""
    rows = []
    for i, values in enumerate(zip(*(r.distances for r in results), strict=True)):
        n = len(values)
        mean = statistics.fmean(values)
        half = (float(stats.t.ppf(0.975, n - 1)) * statistics.stdev(values) / math.sqrt(n)
                if n > 1 else math.nan)
        rows.append(InteractionSummary(
            interaction=i + 1, n_trials=n, mean_distance=mean, ci_low=mean - half,
            ci_high=mean + half,
            success_rate=sum(v < SUCCESS_DISTANCE for v in values) / n))
    return rows


class TrialStore:
    """The raw ``trials.csv`` of one condition: atomic per-trial appends, resume."""

    def __init__(self, directory: Path, condition: StudyCondition, seed: int) -> None:
        self.directory = directory
        self.path = directory / "trials.csv"
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
        rows: dict[int, list[dict[str, str]]] = defaultdict(list)
        with self.path.open(newline="") as handle:
            for row in csv.DictReader(handle):
                if None in row.values() or None in row:
                    continue  # a line cut short by an interruption
                rows[int(row["trial"])].append(row)
        complete = {t: r for t, r in rows.items() if len(r) == self.n_interactions}
        if len(complete) != len(rows) or sum(map(len, rows.values())) != sum(
                map(len, complete.values())):
            logger.warning("%s: discarding %d partial trial(s)", self.path,
                           len(rows) - len(complete))
        results = {t: _result_from_rows(t, r) for t, r in complete.items()}
        self._rewrite(results)
        return results

    def append(self, result: TrialResult) -> None:
        """Append one trial's rows with a single ``write`` and flush them to disk."""
        new_file = not self.path.exists() or self.path.stat().st_size == 0
        data = _rows_text(result, header=new_file).encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)

    def _rewrite(self, results: dict[int, TrialResult]) -> None:
        tmp = self.path.with_suffix(".csv.tmp")
        text = "".join(_rows_text(results[t], header=i == 0) for i, t in enumerate(sorted(results)))
        tmp.write_text(text or _rows_text(None, header=True))
        os.replace(tmp, self.path)


def _rows_text(result: TrialResult | None, header: bool) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    if header:
        writer.writerow(TRIAL_COLUMNS)
    if result is not None:
        for i, (d, s) in enumerate(zip(result.distances, result.shown_distances, strict=True)):
            writer.writerow((result.trial, i + 1, repr(d), repr(s), result.fit_failures,
                             f"{result.seconds:.4f}"))
    return buffer.getvalue()


def _result_from_rows(trial: int, rows: list[dict[str, str]]) -> TrialResult:
    rows = sorted(rows, key=lambda r: int(r["interaction"]))
    return TrialResult(trial=trial, distances=[float(r["distance"]) for r in rows],
                       shown_distances=[float(r["shown_distance"]) for r in rows],
                       fit_failures=int(rows[0]["fit_failures"]),
                       seconds=float(rows[0]["seconds"]))


def write_summary(path: Path, rows: list[InteractionSummary]) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(row.model_dump() for row in rows)


def _init_trial_process() -> None:
    """Each trial process runs torch single-threaded: parallelism comes from the processes."""
    import torch

    torch.set_num_threads(1)


def run_condition(condition: StudyCondition, *, trials: int, seed: int, jobs: int, out: Path,
                  progress: bool = True) -> tuple[ConditionSummary, list[InteractionSummary]]:
    """Run (or resume) ``trials`` trials of ``condition`` and write its CSV files under ``out``."""
    directory = out / condition.name
    store = TrialStore(directory, condition, seed)
    results = {t: r for t, r in store.load().items() if t < trials}
    todo = [t for t in range(trials) if t not in results]
    if results:
        logger.info("%s: resuming, %d of %d trials already done", condition.name, len(results),
                    trials)
    bar = tqdm(total=trials, initial=len(results), desc=condition.name, unit="trial",
               disable=not progress, mininterval=2.0, dynamic_ncols=True)
    fresh: list[TrialResult] = []
    start = time.monotonic()

    def done(result: TrialResult) -> None:
        store.append(result)
        results[result.trial] = result
        fresh.append(result)
        bar.update()

    if jobs == 1:
        for trial in todo:
            done(run_trial(condition, seed, trial))
    else:
        with ProcessPoolExecutor(max_workers=jobs, mp_context=get_context("spawn"),
                                 initializer=_init_trial_process) as pool:
            futures = [pool.submit(run_trial, condition, seed, trial) for trial in todo]
            for future in as_completed(futures):
                done(future.result())
    bar.close()
    wall = time.monotonic() - start
    ordered = [results[t] for t in sorted(results)]
    rows = summarise(ordered)
    write_summary(directory / "summary.csv", rows)
    timed = fresh or ordered
    final = rows[-1]
    summary = ConditionSummary(
        condition=condition.name, acquisition=condition.acquisition.value, q=condition.q,
        noise=condition.noise, trials=len(ordered), interactions=len(rows),
        final_mean_distance=final.mean_distance, final_ci=(final.ci_low, final.ci_high),
        final_success_rate=final.success_rate,
        seconds_per_trial=statistics.fmean(r.seconds for r in timed),
        wall_seconds_per_trial=wall / len(fresh) if fresh else None,
        fit_failures=sum(r.fit_failures for r in ordered), out_dir=str(directory))
    return summary, rows

"""CPU time of what the serving process does at the end of every trial: store the trial's samples
and refresh the study overview the dashboard shows.

    python benchmarks/trial_end.py [--runs 7]

Samples: one simulated 500 Hz handover of the perturbed scenario, stored by
``ParticipantStore.add_samples`` (one ``executemany``) against the baseline of the same run, the same
rows through sqlite-utils' ``insert_all`` (what add_samples did before). Overview: a participant of a
whole session on the paper's protocol (500 Hz, run with ``handover run-session --auto``); a line read
afresh (``summarise``: a copy of the database in memory and its events replayed, which every refresh
did for every participant before) against a refresh of ``StudyOverview`` where that participant's
database did not change, and against the open session's line read from its own store. Medians of
``--runs`` CPU times (``time.process_time``).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from app.session.overview import StudyOverview, summarise, summary_of
from robot_io.config import ControllerConfig
from robot_io.control.trial import simulate_trial
from robot_io.hands.simulated_hand import Scenario
from robot_io.theta import Theta
from session_store.schema import sample_column_names
from session_store.store import ParticipantStore, sample_matrix


def cpu_ms(action: Callable[[], object], runs: int) -> float:
    """Median CPU milliseconds of ``action`` over ``runs`` runs."""
    times = []
    for _ in range(runs):
        began = time.process_time()
        action()
        times.append(1e3 * (time.process_time() - began))
    return statistics.median(times)


def insert_all(store: ParticipantStore, trial_index: int, columns: dict[str, np.ndarray]) -> None:
    """The baseline: a trial's rows as dicts through sqlite-utils' insert_all."""
    names, matrix = sample_column_names(), sample_matrix(columns)
    matrix = np.where(np.isfinite(matrix), matrix, np.nan)
    rows = ({"trial_index": trial_index, "cycle": cycle,
             **{n: (None if v != v else float(v)) for n, v in zip(names, row, strict=True)}}
            for cycle, row in enumerate(matrix.tolist()))
    store.db["samples"].insert_all(rows, batch_size=500)


def samples(folder: Path, runs: int) -> None:
    record = simulate_trial(ControllerConfig(), Theta(a=5.0, delta=-0.2, k=15.0),
                            Scenario.PERTURBED, 0)
    store = ParticipantStore.create(folder / "samples", "B01", ControllerConfig())
    store.db.execute("PRAGMA foreign_keys=OFF")  # rows without their trials: this measures the write
    index = iter(range(10**6))
    rows = len(record.samples["t"])
    baseline = cpu_ms(lambda: insert_all(store, next(index), record.samples), runs)
    now = cpu_ms(lambda: store.add_samples(next(index), record.samples), runs)
    store.close()
    print(f"samples of one trial ({rows} rows × {len(sample_column_names()) + 2} columns): "
          f"add_samples {now:.1f} ms CPU; baseline insert_all {baseline:.1f} ms "
          f"({baseline / now:.1f}×)")


def overview(folder: Path, runs: int) -> None:
    study = folder / "study"
    subprocess.run([sys.executable, "-m", "app.cli", "run-session", "--study", str(study),
                    "--participant", "B01", "--scenario", "perturbed", "--auto", "--seed", "1",
                    "--no-progress"], check=True, capture_output=True)
    size = (study / "B01.sqlite").stat().st_size / 1e6
    kept = StudyOverview(study)
    kept.lines()
    fresh = cpu_ms(lambda: summarise(study, "B01"), runs)
    unchanged = cpu_ms(kept.lines, runs)
    store = ParticipantStore.open(study, "B01")
    own = cpu_ms(lambda: summary_of(store, "B01", "B01"), runs)
    store.close()
    print(f"overview line of a whole session ({size:.1f} MB): unchanged, kept {unchanged:.2f} ms "
          f"CPU; the open session's, from its store {own:.1f} ms; baseline read afresh "
          f"{fresh:.1f} ms ({fresh / unchanged:.0f}× and {fresh / own:.1f}×). Before, every trial "
          f"end read every participant afresh: N × {fresh:.0f} ms for a study of N.")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        samples(Path(folder), args.runs)
        overview(Path(folder), args.runs)


if __name__ == "__main__":
    main()

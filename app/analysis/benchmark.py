"""Fig. 3 of the paper from a ``handover benchmark-pl`` result folder (Sect. IV).

The folder holds one sub-folder per condition (``condition.json``, ``summary.csv``, ``trials.csv``;
see ``app.learning.study``). This module reads them back into the learning package's own summaries
and draws them with its :func:`app.learning.figures.draw_figure3`, so the report's Fig. 3 is the
benchmark's.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from app.analysis.figures import FigureFiles
from app.learning.cli import PAPER_CONDITIONS
from app.learning.figures import draw_figure3
from app.learning.simulation import StudyCondition
from app.learning.study import SUMMARY_COLUMNS, ConditionSummary, InteractionSummary

PAPER_ORDER = [StudyCondition(acquisition=acq, q=q, noise=noise).name
               for acq, q, noise in PAPER_CONDITIONS]


class BenchmarkError(ValueError):
    """A folder that is not a benchmark-pl result."""


def load_condition(directory: Path) -> tuple[ConditionSummary, list[InteractionSummary]]:
    """One condition's summary rows and its :class:`ConditionSummary` (no wall time: not stored)."""
    missing = [name for name in ("condition.json", "summary.csv", "trials.csv")
               if not (directory / name).is_file()]
    if missing:
        raise BenchmarkError(f"{directory} is not a benchmark-pl condition folder: no {missing}")
    condition = StudyCondition.model_validate(
        json.loads((directory / "condition.json").read_text())["condition"])
    summary = pd.read_csv(directory / "summary.csv")
    if list(summary.columns) != list(SUMMARY_COLUMNS) or summary.empty:
        raise BenchmarkError(f"{directory / 'summary.csv'} has columns {list(summary.columns)} and "
                             f"{len(summary)} rows; expected {list(SUMMARY_COLUMNS)} and rows")
    rows = [InteractionSummary.model_validate(row) for row in summary.to_dict("records")]
    per_trial = pd.read_csv(directory / "trials.csv").groupby("trial").first()
    final = rows[-1]
    return ConditionSummary(
        condition=condition.name, acquisition=condition.acquisition.value, q=condition.q,
        noise=condition.noise, trials=final.n_trials, interactions=len(rows),
        final_mean_distance=final.mean_distance, final_ci=(final.ci_low, final.ci_high),
        final_success_rate=final.success_rate,
        seconds_per_trial=float(per_trial["seconds"].mean()), wall_seconds_per_trial=None,
        fit_failures=int(per_trial["fit_failures"].sum()), out_dir=str(directory)), rows


def load_benchmark(folder: Path) -> list[tuple[ConditionSummary, list[InteractionSummary]]]:
    """Every condition under ``folder``, in the paper's order (others after, by name)."""
    directories = sorted(p.parent for p in Path(folder).glob("*/summary.csv"))
    if not directories:
        raise BenchmarkError(f"{folder} holds no benchmark-pl condition (*/summary.csv); run "
                             "`handover benchmark-pl --paper --out FOLDER` first")
    results = [load_condition(d) for d in directories]
    rank = {name: i for i, name in enumerate(PAPER_ORDER)}
    return sorted(results, key=lambda r: (rank.get(r[0].condition, len(rank)), r[0].condition))


def draw_benchmark_figure3(folder: Path, directory: Path, stem: str = "fig3") -> FigureFiles:
    """Fig. 3 (PNG and SVG) of the benchmark in ``folder``, written under ``directory``."""
    results = load_benchmark(folder)
    files = FigureFiles(png=directory / f"{stem}.png", svg=directory / f"{stem}.svg")
    for path in (files.png, files.svg):
        draw_figure3(results, path)
    return files

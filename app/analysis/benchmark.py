"""Fig. 3 of the paper from a ``handover benchmark-pl`` result folder (Sect. IV).

The folder holds one sub-folder per condition (``condition.json``, ``trials.csv``, ``timings.csv``,
``summary.csv``; see ``app.learning.simulated_study``). This module recomputes the learning package's own
summaries from the raw trials with the package's functions and draws them with its
:func:`app.learning.figures.draw_figure3`, so the report's Fig. 3 is the benchmark's.
"""

from __future__ import annotations

import json
from pathlib import Path

from app.analysis.figures import FigureFiles
from app.learning.cli import PAPER_CONDITIONS
from app.learning.figures import draw_figure3
from app.learning.simulated_study import (
    ConditionSummary,
    InteractionSummary,
    condition_summary,
    read_trials,
    summarise,
)
from app.learning.simulation import StudyCondition

PAPER_ORDER = [StudyCondition(acquisition=acq, q=q, noise=noise).name
               for acq, q, noise in PAPER_CONDITIONS]


class BenchmarkError(ValueError):
    """A folder that is not a benchmark-pl result."""


def load_condition(directory: Path) -> tuple[ConditionSummary, list[InteractionSummary]]:
    """One condition's :class:`ConditionSummary` and per-interaction rows, recomputed from its raw
    ``trials.csv`` (and ``timings.csv`` for the seconds per trial; no wall time: not stored)."""
    missing = [name for name in ("condition.json", "trials.csv") if not (directory / name).is_file()]
    if missing:
        raise BenchmarkError(f"{directory} is not a benchmark-pl condition folder: no {missing}")
    try:
        condition = StudyCondition.model_validate(
            json.loads((directory / "condition.json").read_text())["condition"])
        results = read_trials(directory, condition.schedule.n_interactions)
    except (ValueError, KeyError) as exc:
        raise BenchmarkError(f"{directory} holds an unreadable benchmark-pl condition: {exc}"
                             ) from exc
    if not results:
        raise BenchmarkError(f"{directory / 'trials.csv'} holds no complete trial of "
                             f"{condition.schedule.n_interactions} interactions")
    ordered = [results[t] for t in sorted(results)]
    rows = summarise(ordered)
    return condition_summary(condition, ordered, rows, directory, [r.seconds for r in ordered],
                             None), rows


#: A benchmark-pl result folder as loaded: each condition's summary and its interactions.
Benchmark = list[tuple[ConditionSummary, list[InteractionSummary]]]


def load_benchmark(folder: Path) -> Benchmark:
    """Every condition under ``folder``, in the paper's order (others after, by name)."""
    directories = sorted(p.parent for p in Path(folder).glob("*/condition.json"))
    if not directories:
        raise BenchmarkError(f"{folder} holds no benchmark-pl condition (*/condition.json); run "
                             "`handover benchmark-pl --paper --out FOLDER` first")
    results = [load_condition(d) for d in directories]
    rank = {name: i for i, name in enumerate(PAPER_ORDER)}
    return sorted(results, key=lambda r: (rank.get(r[0].condition, len(rank)), r[0].condition))


def draw_benchmark_figure3(results: Benchmark, directory: Path, stem: str = "fig3") -> FigureFiles:
    """Fig. 3 (PNG and SVG) of a loaded benchmark (:func:`load_benchmark`), written under
    ``directory``."""
    files = FigureFiles(png=directory / f"{stem}.png", svg=directory / f"{stem}.svg")
    for path in (files.png, files.svg):
        draw_figure3(results, path)
    return files

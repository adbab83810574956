"""``handover report``: a study folder → the paper's tables (CSV), figures (PNG + SVG) and one
self-contained HTML page (Sect. VI, Tables II–IV, Fig. 4; Fig. 3 from a benchmark-pl folder).

Reading is tolerant in one way only: a database that cannot be opened (another schema version, a
corrupt or foreign file) is left out, named with the reason at the top of the report and logged as a
warning, and the other participants are reported. An empty folder, or one with nothing readable, is an
error. A participant whose session stopped mid-protocol is reported with what they did and marked
incomplete; the statistical tests use complete sessions only.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path

import pandas as pd
from pydantic import BaseModel

from app.analysis import figures as fig
from app.analysis.provenance import SIMULATED_MARK, Counting, answers_not_used, not_blind
from app.analysis.recordings import go_check, recorded_runs, recordings_section, stored_gos
from app.analysis.report_page import render_page
from app.analysis.safety import (
    draw_replays,
    judged_by_lab_limits,
    over_text,
    safety_section,
    safety_summary,
)
from app.analysis.stats import StatTest
from app.analysis.study_analysis import StudyAnalysis
from app.analysis.study_design import StudyDesign
from app.analysis.tables import study_configs, theta_star
from app.analysis.xdf import Recording, around_go, load_recording
from robot_io.control.stages import Stage
from session_store.export import load_study, refuse_inside_study

log = logging.getLogger(__name__)

#: The export tables the report reads (samples of the validation trials only: Fig. 4).
REPORT_TABLES = ("participants", "trials", "placements", "hints", "validation_ratings", "answers",
                 "learner_snapshots", "events", "samples")
TABLE_FILES = {"straightforward": "table2_straightforward", "perturbed": "table3_perturbed"}
LEARNING_PHASES = ("initial", "learning", "best")


class Report(BaseModel):
    """What ``build_report`` wrote, and the problems it reported."""

    html: Path
    tables: dict[str, Path]
    figures: dict[str, fig.FigureFiles]
    tests: list[StatTest]
    incomplete: list[str]
    unreadable: dict[str, str]
    ratings_counted: str  # whose answers were counted, in words
    counting: Counting  # … and which participants were left out or marked, and why
    answers_not_used: list[str]  # answers recorded as not used (two at once), per participant
    design: StudyDesign  # the study plan's line and the deviations from it
    not_blind: dict[str, str]  # participant → how their validation was shown, where not "blind"
    recording_cut_short: list[str] = []  # the XDF recording's streams that end early, in words
    #: participant → the stored trials whose Go marker none of the study's own recordings holds
    gos_not_recorded: dict[str, str] = {}
    #: each trial that went past the lab's [safety_record] limits in force when it was stored
    safety_over_limits: list[str] = []


def tests_frame(tests: list[StatTest]) -> pd.DataFrame:
    """The tests as a table (``groups`` as JSON)."""
    return pd.DataFrame([t.model_dump() | {"groups": json.dumps(t.groups)} for t in tests])


def write_tables(analysis: StudyAnalysis, directory: Path) -> dict[str, Path]:
    """The report's tables as CSV files under ``directory``."""
    directory.mkdir(parents=True, exist_ok=True)
    frames = {"sessions": analysis.status, "validation_pairs": analysis.pairs,
              "table4_survey": analysis.survey, "statistics": tests_frame(analysis.tests),
              "learning": analysis.learning, "cycle": analysis.cycle}
    for scenario, name in TABLE_FILES.items():
        frames[name] = analysis.scores[analysis.scores["scenario"] == scenario]
    paths = {}
    for name, frame in frames.items():
        paths[name] = directory / f"{name}.csv"
        frame.to_csv(paths[name], index=False)
    return paths


def draw_participant_figures(analysis: StudyAnalysis, directory: Path) -> dict[str, fig.FigureFiles]:
    """Fig. 4 and the learning curve of every participant that has the data for them: a completed
    validation trial, a completed handover before the validation and a learner update. The others
    are left out of the figures (the page names them)."""
    configs = study_configs(analysis.tables["participants"])
    marked = set(analysis.counting.marked)
    trials = analysis.tables["trials"]
    learning = trials[(trials["outcome"] == "completed") & trials["phase"].isin(LEARNING_PHASES)]
    snapshots = analysis.tables["learner_snapshots"]
    stars = theta_star(snapshots).set_index("participant")
    drawn = {}
    for code, config in configs.items():
        title = f"{code}{f' {SIMULATED_MARK}' if code in marked else ''} ({config.scenario.value})"
        mine = analysis.distances[analysis.distances["participant"] == code]
        if not mine.empty:
            star = stars.loc[code]
            theta = fig.theta_text(star["theta_a"], star["theta_delta"], star["theta_k"])
            drawn[f"fig4-{code}"] = fig.save(fig.draw_fig4(mine, f"Fig. 4, {title}", theta),
                                             directory, f"fig4-{code}")
        shown = learning[learning["participant"] == code]
        if not shown.empty and (snapshots["participant"] == code).any():
            curve = fig.draw_learning_curve(shown,
                                            snapshots[snapshots["participant"] == code], config,
                                            f"Learning curve, {title}")
            drawn[f"learning-{code}"] = fig.save(curve, directory, f"learning-{code}")
    return drawn


def draw_recording_figures(recording: Recording, aligned: pd.DataFrame, out_dir: Path
                           ) -> tuple[Path, dict[str, fig.FigureFiles]]:
    """The lab's streams of an XDF recording around each trial's Go (``aligned``:
    :func:`~app.analysis.xdf.around_go`): ``tables/xdf_around_go.csv`` and a figure per stream
    (``figures/xdf-STREAM-CODE``)."""
    table = out_dir / "tables" / "xdf_around_go.csv"
    aligned.to_csv(table, index=False)
    release = list(recording.trial_times(Stage.RELEASE).values())
    code = recording.participant
    drawn = {}
    for name, frame in aligned.groupby("stream"):
        title = f"{name} around Go, {code} ({frame['trial_index'].nunique()} trials, {recording.path.name})"
        drawn[f"xdf-{name}-{code}"] = fig.save(fig.draw_around_go(frame, release, title),
                                                out_dir / "figures", f"xdf-{name}-{code}")
    return table, drawn


def build_report(study_dir: Path, out_dir: Path, benchmark_dir: Path | None = None,
                 include_simulated: bool = False, exclude: Mapping[Path, str] | None = None,
                 xdf: Path | None = None, xdf_streams: Sequence[str] = ()) -> Report:
    """Analyse ``study_dir`` and write ``report.html``, ``tables/*.csv`` and ``figures/*`` under
    ``out_dir`` (plus Fig. 3 when ``benchmark_dir`` is a benchmark-pl result folder, and the lab's
    streams ``xdf_streams`` — all numeric ones when empty — of the XDF recording ``xdf`` around each
    trial's Go). The inputs are read before anything is written: a refusal leaves ``out_dir`` as it
    was. Only the participants' own answers (and the experimenter's entries for them) count unless
    ``include_simulated`` or no person answered at all (:mod:`app.analysis.provenance`). The
    databases in
    ``exclude`` (path → why) are left out and listed as the unreadable ones are."""
    out_dir = Path(out_dir)
    refuse_inside_study(out_dir, study_dir, "a report")
    if benchmark_dir is not None:  # here: Fig. 3's study code imports torch, a report without it not
        from app.analysis.benchmark import draw_benchmark_figure3, load_benchmark
    loaded = load_study(study_dir, REPORT_TABLES, sample_phases=("validation",),
                        skip_unreadable=True, exclude=exclude)
    benchmark = None if benchmark_dir is None else load_benchmark(benchmark_dir)
    recording = None if xdf is None else load_recording(xdf, xdf_streams)
    aligned = None if recording is None else around_go(recording, loaded.tables["trials"])
    analysis = StudyAnalysis.of(loaded.tables, include_simulated)
    counted = analysis.counting
    tables = write_tables(analysis, out_dir / "tables")
    figures = draw_participant_figures(analysis, out_dir / "figures")
    if benchmark is not None:
        figures["fig3"] = draw_benchmark_figure3(benchmark, out_dir / "figures")
    if recording is not None:
        tables["xdf_around_go"], drawn = draw_recording_figures(recording, aligned, out_dir)
        figures |= drawn
    summary = safety_summary(loaded.tables["trials"])
    tables["safety"] = out_dir / "tables" / "safety.csv"
    summary.to_csv(tables["safety"], index=False)
    figures |= draw_replays(Path(study_dir), summary, out_dir / "figures")
    judged = judged_by_lab_limits(loaded.tables["trials"], loaded.tables["events"])
    tables["safety_limits"] = out_dir / "tables" / "safety_limits.csv"
    judged.to_csv(tables["safety_limits"], index=False)
    participants = loaded.tables["participants"]
    runs, found, unreadable_runs = recorded_runs(
        Path(study_dir), dict(zip(participants["participant"], participants["created_at"],
                                  strict=True)))
    check = go_check(stored_gos(loaded.tables["events"]),
                     {code: gos for code, gos in found.items()
                      if (runs["participant"] == code).any()})
    if not runs.empty:
        tables["recordings"] = out_dir / "tables" / "recordings.csv"
        runs.to_csv(tables["recordings"], index=False)
    unreadable = {str(path): reason for path, reason in loaded.unreadable.items()}
    html = out_dir / "report.html"
    html.write_text(render_page(analysis, figures, study_dir=Path(study_dir), unreadable=unreadable,
                                generated=datetime.now(UTC).isoformat(timespec="seconds"),
                                ratings_counted=counted.text(),
                                recording_cut_short=[] if recording is None else recording.cut_short,
                                extra=[safety_section(summary, figures, judged),
                                       recordings_section(runs, check, unreadable_runs)]))
    incomplete = analysis.status.loc[~analysis.status["complete"], "participant"].tolist()
    if incomplete:
        log.info("incomplete sessions (reported, left out of the tests): %s", incomplete)
    return Report(html=html, tables=tables, figures=figures, tests=analysis.tests,
                  incomplete=incomplete, unreadable=unreadable, ratings_counted=counted.text(),
                  counting=counted, answers_not_used=answers_not_used(analysis.tables["events"]),
                  design=analysis.design,
                  not_blind=not_blind(analysis.status),
                  recording_cut_short=[] if recording is None else recording.cut_short,
                  gos_not_recorded={row.participant: row.missing for row in check.itertuples()
                                    if row.missing},
                  safety_over_limits=over_text(judged))


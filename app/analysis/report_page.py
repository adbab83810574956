"""The HTML page of ``handover report``: sections in the paper's order (Sect. VI: Tables II–III and
the validation sign test, Table IV and the survey tests, Fig. 4), then learning curves, the streams of
an XDF recording (``--xdf``) and Fig. 3."""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from pathlib import Path

import pandas as pd

from app.analysis import html
from app.analysis.figures import FigureFiles
from app.analysis.provenance import (
    ANSWER_KINDS,
    SIMULATED_MARK,
    answers_not_used,
    answers_text,
    not_blind,
)
from app.analysis.stats import MWU_METHOD, SIGN_TIE_RULE, TEST_WORDS, WILCOXON_METHOD, StatTest
from app.analysis.study_analysis import StudyAnalysis
from app.analysis.tables import INDISTINCT_ARRIVAL_S, SCENARIOS
from session_store.vocabulary import questions

TABLE_NUMBER = {"straightforward": "Table II", "perturbed": "Table III"}
SCORE_RULE = (
    "Validation = pairs in which the learned θ* was preferred / rated pairs. A pair rated "
    "'equal' counts as not preferred (it stays in the denominator), as in the paper, where every "
    "score is a multiple of 25 % of 4 pairs. * : a missed pair compared two θ with which the robot "
    f"arrived within {INDISTINCT_ARRIVAL_S * 1000:.0f} ms of each other (practically identical "
    "controllers, as the paper's *75 in Table II). † : incomplete session, left out of the tests "
    f"(its θ* is the learner's best so far). {SIMULATED_MARK} : learning used the simulated "
    "participant's answers (in these tables only with --include-simulated).")
ALTERNATIVE_TEXT = {"greater": "one-sided (above)", "less": "one-sided (below)",
                    "two-sided": "two-sided"}


def _status_text(row: pd.Series) -> str:
    if row["complete"]:
        return "complete"
    return (f"incomplete: stopped in phase {row['phase']}, waiting for {row['waiting_for']} "
            f"({row['completed']}/{row['planned']} interactions)")


def _score_text(row: pd.Series) -> str:
    """The validation score with its n, e.g. "75 % of 4 rated pairs"."""
    if pd.isna(row["score_pct"]):
        return "no rated pair"
    mark = "*" if row["indistinct_missed"] else ""
    pairs = row["pairs"]
    return f"{mark}{row['score_pct']:.0f} % of {pairs} rated pair{'' if pairs == 1 else 's'}"


def _marked(row: pd.Series, marked: Collection[str]) -> str:
    """The participant's code, marked § when it is one of ``marked``: its learning used the
    simulated participant's answers (:attr:`~app.analysis.provenance.Counting.marked`)."""
    return row["participant"] + (f" {SIMULATED_MARK}" if row["participant"] in marked else "")


def _participant_text(row: pd.Series, marked: Collection[str]) -> str:
    return _marked(row, marked) + ("" if row["complete"] else " †")


def unreadable_text(path: str, reason: str) -> str:
    """Why a database was left out, naming the file once."""
    return f"not read, left out: {reason if path in reason else f'{path}: {reason}'}"


def problems(analysis: StudyAnalysis, unreadable: Mapping[str, str],
             recording_cut_short: Sequence[str] = ()) -> str:
    lines = [unreadable_text(path, reason) for path, reason in unreadable.items()]
    lines += [f"XDF recording: {why}; its figures stop where it does" for why in recording_cut_short]
    lines += [f"{row['participant']}: {_status_text(row)}; shown below, left out of the tests"
              for _, row in analysis.status.iterrows() if not row["complete"]]
    lines += [f"{code}: validation {text}: the dashboard showed the experimenter which trial of a "
              "pair was θ*" for code, text in not_blind(analysis.status).items()]
    counting = analysis.counting
    lines += answers_not_used(analysis.tables["events"])
    lines += [f"study plan: {deviation}" for deviation in analysis.design.deviations]
    lines += [f"{code} {SIMULATED_MARK}: {counting.problem(code)}" for code in counting.marked]
    if not lines:
        return html.paragraph("No problems: every database was read and every session is complete.")
    return html.section("Data problems", html.items(lines, "problem"))


def sessions(analysis: StudyAnalysis) -> str:
    frame = analysis.status.assign(progress=lambda f: f["completed"].astype(str) + "/"
                                   + f["planned"].astype(str),
                                   state=analysis.status.apply(_status_text, axis=1),
                                   who=analysis.status.apply(_marked, axis=1,
                                                             marked=analysis.counting.marked))
    return html.section("Sessions", html.table(
        frame, {"who": "Participant", "scenario": "Scenario",
                "progress": "Interactions", "state": "Status",
                "validation_blinding": "Validation shown to the experimenter"}))


def who_answered(analysis: StudyAnalysis) -> str:
    """Per participant and kind of answer, who gave them: the participant on the tablet, the
    experimenter on their behalf, the simulated participant (or an unrecorded origin)."""
    marked = analysis.counting.marked
    frame = analysis.learning.assign(who=analysis.learning.apply(_marked, axis=1, marked=marked), **{
        kind: analysis.learning.apply(answers_text, axis=1, kind=kind)
        for kind in ANSWER_KINDS.values()})
    return html.section("Who gave the answers", html.table(
        frame, {"who": "Participant", "placements": "Placements", "hints": "Hints",
                "validation": "Validation ratings", "questionnaire": "Questionnaire"}),
        html.paragraph("participant: on the tablet; experimenter: entered on the participant's "
                       "behalf; simulated: the simulated participant (\"Simulated participant "
                       "rates\", run-session --auto); unrecorded: stored before the origin was "
                       "recorded (schema version < 3), counted as the participant's.", "note"))


def learning(analysis: StudyAnalysis) -> str:
    """Per participant: the interactions learning used, where and why it ended, ties and hints."""
    frame = analysis.learning.assign(who=analysis.learning.apply(
        _marked, axis=1, marked=analysis.counting.marked))
    return html.section("Learning: interactions used, why it ended, ties, hints", html.table(
        frame, {"who": "Participant", "learning_interactions": "Interactions "
                            "learned from", "schedule_interactions": "of the schedule",
                            "learning_ended": "Learning ended", "why": "Why",
                            "ties_placed": "\"equal\" placements", "ties": "Ties",
                            "hints_given": "Hints given", "hints_asked": "of those asked"}))


def cycle(analysis: StudyAnalysis) -> str:
    """Per stage of the handover cycle: the trials that reached it and the time spent in it."""
    return html.section("The handover cycle: time in each stage", html.table(
        analysis.cycle, {"stage": "Stage", "trials": "Trials", "median_s": "Median [s]",
                         "longest_s": "Longest [s]"}))


def validation_tables(analysis: StudyAnalysis) -> str:
    parts = []
    for scenario in SCENARIOS:
        rows = analysis.scores[analysis.scores["scenario"] == scenario]
        if rows.empty:
            continue
        rows = rows.assign(shown=rows.apply(_score_text, axis=1),
                           who=rows.apply(_participant_text, axis=1,
                                          marked=analysis.counting.marked))
        parts.append(html.section(
            f"{TABLE_NUMBER[scenario]}: validation results, {scenario} handover",
            html.table(rows, {"who": "Participant", "theta_a": "a_d", "theta_delta": "δ_d",
                              "theta_k": "k", "shown": "Validation", "pairs": "pairs",
                              "learned_preferred": "θ* preferred", "sobol_preferred":
                              "Sobol preferred", "equal": "equal"}), level=3))
    return html.section("Validation (Sect. VI-A)", *parts, html.paragraph(SCORE_RULE, "note"))


def statistics(tests: list[StatTest]) -> str:
    frame = pd.DataFrame([{
        "name": t.name, "test": TEST_WORDS[t.test],
        "sides": ALTERNATIVE_TEXT[t.alternative], "n": t.n, "n_total": t.n_total, "ties": t.n_ties,
        "groups": ", ".join(f"{k} {v}" for k, v in t.groups.items()),
        "statistic": t.statistic_text(), "p": t.p_text()} for t in tests])
    rules = [f"Sign test: exact binomial (p = ½); {SIGN_TIE_RULE}. Statistic S = number of values "
             "above the threshold; H1: values lie above it (the paper's directional hypotheses).",
             f"Mann–Whitney U: two-sided, {MWU_METHOD}; U is that of the first group "
             "(straightforward); 'ties' counts the answers that share a rank."
             if any(t.test == "mann-whitney-u" for t in tests) else
             f"Wilcoxon signed-rank (a within-subjects plan: each person's straightforward answer "
             f"minus their perturbed one): two-sided, {WILCOXON_METHOD}; W is the smaller of the "
             "two signed rank sums; 'ties' counts the zero differences. The sign tests take each "
             "person once, the mean of their complete sessions.",
             "Only complete sessions enter the tests."]
    return html.section("Statistics (Sect. VI)", html.table(frame, {
        "name": "Hypothesis", "test": "Test", "sides": "Sidedness", "n": "N used",
        "n_total": "N given", "ties": "ties", "groups": "counts", "statistic": "statistic",
        "p": "p"}), html.items(rules, "note"))


def survey(analysis: StudyAnalysis) -> str:
    parts = []
    for scenario in SCENARIOS:
        rows = analysis.survey[analysis.survey["scenario"] == scenario]
        if not rows.empty:
            rows = rows.assign(who=rows.apply(_participant_text, axis=1,
                                              marked=analysis.counting.marked))
            parts.append(html.section(f"{scenario.capitalize()}", html.table(
                rows, {"who": "Participant", **{q.id: q.id for q in questions()}}), level=3))
    notes = [f"{q.id}: {q.paper_text.removesuffix('.')} ({q.scale})"
             + ("." if q.paper_text.endswith(".") else "") for q in questions()]
    return html.section("Table IV: survey results (Sect. VI-B)", *parts, html.items(notes, "note"))


def figure_list(figures: Mapping[str, FigureFiles], prefix: str, caption: str,
                marked: Collection[str] = ()) -> list[str]:
    """The figures named ``prefix``-CODE, captioned with the code (``marked``: the codes to mark
    §)."""
    codes = {name: name.removeprefix(prefix) for name in figures if name.startswith(prefix)}
    return [html.figure(figures[name].png, f"{caption} {code}"
                        + (f" {SIMULATED_MARK}" if code in marked else ""))
            for name, code in codes.items()]


def left_out(analysis: StudyAnalysis, figures: Mapping[str, FigureFiles], prefix: str,
             why: str) -> list[str]:
    """A note naming the participants without a figure ``prefix``-CODE, and why ([] if none)."""
    missing = [code for code in analysis.status["participant"] if f"{prefix}{code}" not in figures]
    return [html.paragraph(f"Not drawn for {', '.join(missing)}: {why}.", "note")] if missing else []


def render_page(analysis: StudyAnalysis, figures: Mapping[str, FigureFiles], *, study_dir: Path,
                unreadable: Mapping[str, str], generated: str, ratings_counted: str,
                recording_cut_short: Sequence[str] = (), extra: Sequence[str] = ()) -> str:
    """The whole report as one HTML string (figures embedded); ``ratings_counted`` says whose
    ratings it counts, ``recording_cut_short`` which streams of the XDF recording end early;
    ``extra``: sections after the learning curves (the safety record, the recordings)."""
    counts = analysis.status["scenario"].value_counts()
    marked = analysis.counting.marked
    intro = html.paragraph(
        f"Study folder {study_dir}, {len(analysis.status)} participants ("
        + ", ".join(f"{counts.get(s, 0)} {s}" for s in SCENARIOS) + f"). Generated {generated}.")
    fig4 = figure_list(figures, "fig4-", "Fig. 4: human (red) and robot (blue) distance to the "
                       "handover point, normalised by the distance at the start, validation trials:",
                       marked)
    curves = figure_list(figures, "learning-", "θ over interactions and θ*'s posterior utility:",
                         marked)
    banner = ([html.paragraph(ratings_counted, "banner")] if analysis.counting.simulated_study
              else [])
    parts = [*banner, intro, html.paragraph(analysis.design.line),
             *([] if banner else [html.paragraph(ratings_counted)]),
             problems(analysis, unreadable, recording_cut_short),
             sessions(analysis), who_answered(analysis), learning(analysis), cycle(analysis),
             validation_tables(analysis),
             statistics(analysis.tests), survey(analysis),
             html.section("Fig. 4: trajectories of the validation trials (Sect. VI-C)", *fig4,
                          *left_out(analysis, figures, "fig4-", "no completed validation trial")),
             html.section("Learning curves", *curves,
                          *left_out(analysis, figures, "learning-",
                                    "no completed handover before the validation, or no learner "
                                    "update")), *extra]
    recorded = figure_list(figures, "xdf-", "A stream of the lab's XDF recording around each trial's "
                           "Go, by θ origin; black: the mean of the completed trials:")
    if recorded:
        parts.append(html.section("Other streams of the XDF recording", *recorded))
    if "fig3" in figures:
        parts.append(html.section("Fig. 3: simulated study (Sect. IV)", html.figure(
            figures["fig3"].png, "Mean distance to the target (95 % CI) and success rate")))
    return html.page(f"Handover study report: {study_dir.name}", *parts)

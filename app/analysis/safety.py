"""The report's safety record (issue 47): each trial's figures (docs/data.md, "The safety record of
every trial") summarised per participant and for the study — the median, the extreme (the closest
distance, the largest of the rest) and the trial it happened in, whose replay (the tool–hand
distance, the tool's speed and the pull over the trial) is drawn below the table and linked from it;
and every trial past the lab's own limits, judged as the dashboard flagged it when it was stored."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from app.analysis import html
from app.analysis.figures import FigureFiles, save
from app.analysis.tables import events_of
from app.protocol.safety_record import (
    JUDGED,
    SafetyRecordSettings,
    over_limits,
    safety_record,
)
from session_store.paths import participant_path
from session_store.sample_rows import read_samples

#: Each figure's words and unit, in the order of the record.
NAMES = {"min_distance_m": ("closest tool–hand distance", "m"),
         "speed_near_mps": ("tool speed, hand near", "m/s"),
         "closing_speed_mps": ("closing speed, hand near", "m/s"),
         "peak_pull_n": ("peak pull", "N"),
         "pull_to_open_s": ("pull to open", "s"),
         "longest_contact_s": ("longest contact", "s")}
FLOORS = {figure for figure, _, floor in JUDGED if floor}


def safety_summary(trials: pd.DataFrame) -> pd.DataFrame:
    """One row per scope (each participant, then ``study``) and figure: ``n`` trials with it, the
    ``median``, the ``extreme`` (min for a distance, else max), the ``participant`` and
    ``trial_index`` where it happened."""
    rows = []
    scopes = [(code, trials[trials["participant"] == code]) for code in
              sorted(trials["participant"].unique())] + [("study", trials)]
    for scope, frame in scopes:
        for figure in NAMES:
            values = frame[["participant", "trial_index", figure]].dropna()
            if values.empty:
                continue
            at = values[figure].astype(float).idxmin() if figure in FLOORS else \
                values[figure].astype(float).idxmax()
            rows.append({"scope": scope, "figure": figure, "n": len(values),
                         "median": float(values[figure].median()),
                         "extreme": float(values.loc[at, figure]),
                         "participant": values.loc[at, "participant"],
                         "trial_index": int(values.loc[at, "trial_index"])})
    return pd.DataFrame(rows, columns=["scope", "figure", "n", "median", "extreme", "participant",
                                       "trial_index"])


def lab_limits(settings: SafetyRecordSettings) -> str:
    """The limits ``settings`` set, in words (``min_distance_m 0.05, max_pull_n 20``), or ""."""
    return ", ".join(f"{limit} {value:g}" for _, limit, _ in JUDGED
                     if (value := getattr(settings, limit)) is not None)


def judged_by_lab_limits(trials: pd.DataFrame, events: pd.DataFrame) -> pd.DataFrame:
    """Every stored trial judged as the dashboard judged it when it was stored
    (:func:`~app.protocol.safety_record.over_limits`), by the ``[safety_record]`` in force then: the
    one the latest ``devices_recorded`` before its ``trial_ended`` carries (a session recorded
    with none is judged by the defaults: no limit, a contact held past ``contact_hold_s``).
    Columns: ``participant``, ``trial_index``, ``limits`` (those in force, in words; "" for none)
    and ``over`` (what went past them, in words; "" for nothing)."""
    rows = []
    figures = trials.set_index(["participant", "trial_index"])
    for code in sorted(events["participant"].unique()):
        settings = SafetyRecordSettings()
        for event in events_of(events, code):
            if event.kind == "devices_recorded":
                settings = SafetyRecordSettings.model_validate(
                    event.payload["config"].get("safety_record", {}))
            elif event.kind == "trial_ended" and (code, index := event.payload["trial_index"]) \
                    in figures.index:
                row = {name: None if isinstance(value, float) and math.isnan(value) else value
                       for name, value in figures.loc[(code, index)].items()}
                rows.append({"participant": code, "trial_index": index,
                             "limits": lab_limits(settings),
                             "over": "; ".join(over_limits(row, settings))})
    return pd.DataFrame(rows, columns=["participant", "trial_index", "limits", "over"])


def replay_name(code: str, trial_index: int) -> str:
    return f"safety-{code}-{trial_index}"


def draw_replays(study_dir: Path, summary: pd.DataFrame, directory: Path) -> dict[str, FigureFiles]:
    """The replay of every trial where a study-wide extreme happened: distance, speed and pull."""
    drawn = {}
    extremes = summary[summary["scope"] == "study"][["participant", "trial_index"]].drop_duplicates()
    for code, index in extremes.itertuples(index=False):
        rows = read_samples(participant_path(study_dir, code), [index])[index]
        figure, axes = plt.subplots(3, 1, figsize=(7, 5.5), sharex=True)
        t, tool = rows["t"], rows["measured"]
        distance = np.linalg.norm(tool - rows["hand"], axis=1)
        speed = np.linalg.norm(np.gradient(tool, t, axis=0), axis=1) if len(t) > 1 else t * 0
        record = safety_record(rows, SafetyRecordSettings())
        axes[0].plot(t, distance, color="tab:red")
        axes[0].axhline(record.near_radius_m or 0.0, color="grey", ls=":", label="near radius")
        axes[0].set_ylabel("tool–hand [m]")
        axes[0].legend(loc="upper right")
        axes[1].plot(t, speed, color="tab:blue")
        axes[1].set_ylabel("tool speed [m/s]")
        axes[2].plot(t, rows["pull"], color="tab:green")
        axes[2].set_ylabel("pull [N]")
        axes[2].set_xlabel("t since Go [s]")
        figure.suptitle(f"Trial {index} of {code}: the tool, the hand and the pull")
        drawn[replay_name(code, index)] = save(figure, directory, replay_name(code, index))
    return drawn


def over_text(judged: pd.DataFrame) -> list[str]:
    """Each trial that went past the lab's limits (``judged``: :func:`judged_by_lab_limits`), in
    words: ``P01 trial 3: peak_pull_n 12 > 5 (max_pull_n)``."""
    return [f"{row.participant} trial {row.trial_index}: {row.over}"
            for row in judged.itertuples() if row.over]


def limits_part(judged: pd.DataFrame) -> list[str]:
    """The section's paragraphs on the lab's limits: those in force per participant, and every trial
    that went past them (highlighted), or that none did."""
    in_force = {code: ", ".join(sorted(set(frame["limits"]) - {""}))
                for code, frame in judged.groupby("participant", sort=True)}
    said = "; ".join(f"{code}: {limits}" for code, limits in in_force.items() if limits)
    parts = [html.paragraph(
        (f"The lab's limits ([safety_record], recorded with each open of a session) in force when "
         f"each trial was stored: {said}." if said else
         "The lab set no limits in [safety_record] (docs/data.md, \"Where the limits come from\"): "
         "only a contact held past contact_hold_s is flagged.")
        + " Each trial is judged as the dashboard flagged it then.")]
    over = over_text(judged)
    if over:
        parts += [html.paragraph(f"{len(over)} of {len(judged)} trials went past them:", "problem"),
                  html.items(over, "problem")]
    elif not judged.empty:
        parts.append(html.paragraph(f"None of the {len(judged)} trials went past them."))
    return parts


def safety_section(summary: pd.DataFrame, figures: dict[str, FigureFiles],
                   judged: pd.DataFrame) -> str:
    """The report page's "Safety record" section (``judged``: :func:`judged_by_lab_limits`)."""
    if summary.empty:
        return html.section("Safety record", html.paragraph(
            "No trial has a safety record (trials stored before schema version 6, or none ended "
            "with samples).", "note"))
    shown = summary.assign(
        figure=[f"{NAMES[f][0]} [{NAMES[f][1]}]" for f in summary["figure"]],
        median=summary["median"].map("{:.3g}".format),
        extreme=[f"{v:.3g} ({'min' if f in FLOORS else 'max'})"
                 for f, v in zip(summary["figure"], summary["extreme"], strict=True)],
        trial=[f"{p} trial {i}" for p, i in zip(summary["participant"], summary["trial_index"],
                                                strict=True)])
    table = html.table(shown, {"scope": "participant", "figure": "figure", "n": "trials",
                               "median": "median", "extreme": "extreme", "trial": "where"})
    names = [name for name in figures if name.startswith("safety-")]
    links = html.paragraph("Replays: ") + " · ".join(
        f'<a href="#{name}">{html.text(name.removeprefix("safety-"))}</a>' for name in names)
    replays = [f'<div id="{name}">' + html.figure(figures[name].png, "Replay: "
                                                  + name.removeprefix("safety-")) + "</div>"
               for name in names]
    return html.section(
        "Safety record", html.paragraph(
            "Every trial's closest tool–hand distance, tool speed and closing speed with the hand "
            "near, peak pull, pull to open and longest contact (docs/data.md, \"The safety "
            "record of every trial\"), per participant and for the study; the trials of the "
            "study's extremes are replayed below (the dashboard replays any trial)."),
        *limits_part(judged), table, links, *replays)

"""The report's safety record (issue 47): each trial's figures (docs/data.md, "The safety record of
every trial") summarised per participant and for the study — the median, the extreme (the closest
distance, the largest of the rest) and the trial it happened in, whose replay (the tool–hand
distance, the tool's speed and the pull over the trial) is drawn below the table and linked from it."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from app.analysis import html
from app.analysis.figures import FigureFiles, save
from app.protocol.safety_record import JUDGED, SafetyRecordSettings, safety_record
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


def safety_section(summary: pd.DataFrame, figures: dict[str, FigureFiles]) -> str:
    """The report page's "Safety record" section."""
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
            "study's extremes are replayed below (the dashboard replays any trial)."), table,
        links, *replays)

"""Figures of the report, each drawn from tidy frames into a matplotlib Figure:

- :func:`draw_fig4`: Fig. 4 for one participant, validation trials with the learned θ* against those
  with the Sobol θ; human in red, robot in blue, as in the paper;
- :func:`draw_learning_curve`: θ shown at each interaction, θ* after each update, and θ*'s posterior
  mean utility (learner snapshots);
- :func:`draw_around_go`: a stream of the lab's XDF recording around each trial's Go, one line per
  trial coloured by θ origin, the mean of the completed trials in black;
- :func:`save`: PNG and SVG side by side.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from pydantic import BaseModel, ConfigDict

from app.analysis.tables import THETA_COLUMNS
from app.protocol.study_config import StudyConfig

HUMAN, ROBOT = "tab:red", "tab:blue"  # the paper's colours (Fig. 4 caption)
ORIGIN_STYLE = {"sobol": ("tab:gray", "o", "Sobol (random)"), "learned": ("tab:orange", "^", "qNEI query"),
                "best": ("tab:green", "s", "θ* (best so far)")}
THETA_LABELS = {"theta_a": "a (σ_j steepness)", "theta_delta": "δ (σ_j offset)", "theta_k": "k (gain)"}
PNG_DPI = 110


class FigureFiles(BaseModel):
    model_config = ConfigDict(frozen=True)

    png: Path
    svg: Path


def save(fig: Figure, directory: Path, stem: str) -> FigureFiles:
    """Write ``fig`` as ``stem.png`` and ``stem.svg`` under ``directory`` and close it."""
    directory.mkdir(parents=True, exist_ok=True)
    files = FigureFiles(png=directory / f"{stem}.png", svg=directory / f"{stem}.svg")
    fig.savefig(files.png, dpi=PNG_DPI)
    fig.savefig(files.svg)
    plt.close(fig)
    return files


def theta_text(a: float, delta: float, k: float) -> str:
    return f"a={a:.2f}, δ={delta:.2f}, k={k:.2f}"


def draw_fig4(distances: pd.DataFrame, title: str, learned_theta: str) -> Figure:
    """Fig. 4 for one participant: ``distances`` (``trajectories.validation_distances`` rows of that
    participant) in two panels, the trials with the learned θ* and those with the Sobol θ."""
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.4), sharex=True, sharey=True)
    panels = (("best", f"learned θ* ({learned_theta})"), ("sobol", "Sobol θ (one per pair)"))
    for ax, (origin, label) in zip(axes, panels, strict=True):
        mine = distances[distances["origin"] == origin]
        for _, trial in mine.groupby("trial_index"):
            hand = trial.dropna(subset=["human"])
            ax.plot(hand["t"], hand["human"], color=HUMAN, linewidth=1.1, alpha=0.75)
            ax.plot(trial["t"], trial["robot"], color=ROBOT, linewidth=1.1, alpha=0.75)
        ax.set_title(f"{label}, {mine['trial_index'].nunique()} trials", fontsize=9)
        ax.set_xlabel("time since Go [s]")
        ax.axhline(0.0, color="black", linewidth=0.6)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("distance to H / distance at start")
    axes[0].set_ylim(bottom=-0.05)
    axes[0].plot([], [], color=HUMAN, label="human hand")
    axes[0].plot([], [], color=ROBOT, label="robot TCP")
    axes[0].legend(loc="upper right", fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def _batch_starts(trials: pd.DataFrame) -> list[float]:
    """x positions between batches (the scale is cleared there)."""
    ordered = trials.sort_values("interaction")
    keys = list(zip(ordered["phase"], ordered["batch"], strict=True))
    return [interaction - 0.5 for before, key, interaction
            in zip(keys, keys[1:], ordered["interaction"].iloc[1:], strict=False) if key != before]


def draw_learning_curve(trials: pd.DataFrame, snapshots: pd.DataFrame, config: StudyConfig,
                        title: str) -> Figure:
    """The learning phase of one participant: θ shown per interaction (by origin), θ* after each
    learner update (black steps), and the posterior mean utility of θ* (bottom panel).

    ``trials``: that participant's completed trials of the initial, learning and best phases;
    ``snapshots``: their ``learner_snapshots`` rows.
    """
    fig, axes = plt.subplots(4, 1, figsize=(7.5, 7.5), sharex=True,
                             gridspec_kw={"height_ratios": [1, 1, 1, 0.9]})
    snapshots = snapshots.sort_values("after_interaction")
    boundaries = _batch_starts(trials)
    for ax, column in zip(axes[:3], THETA_COLUMNS, strict=True):
        name = column.removeprefix("theta_")
        for origin, (colour, marker, label) in ORIGIN_STYLE.items():
            shown = trials[trials["origin"] == origin]
            ax.scatter(shown["interaction"], shown[column], color=colour, marker=marker, s=22,
                       label=label, zorder=3)
        ax.step(snapshots["after_interaction"] + 1, snapshots[f"theta_star_{name}"], where="post",
                color="black", linewidth=1.0, label="θ* after update")
        low, high = config.theta_bounds[name]
        pad = 0.06 * (high - low)  # markers on the bounds stay whole
        ax.set_ylim(low - pad, high + pad)
        ax.set_ylabel(THETA_LABELS[column], fontsize=9)
    axes[3].plot(snapshots["after_interaction"] + 1, snapshots["utility_mean"], color="black",
                 marker=".", linewidth=1.0)
    axes[3].set_ylabel("posterior mean\nutility of θ*", fontsize=9)
    axes[3].set_xlabel("interaction (θ* after an update is used from the next interaction on)")
    for ax in axes:
        for x in boundaries:
            ax.axvline(x, color="tab:gray", linestyle=":", linewidth=0.8)
        ax.grid(alpha=0.25)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.suptitle(title, fontsize=10)
    fig.legend(handles, labels, fontsize=8, ncol=4, loc="upper center", bbox_to_anchor=(0.5, 0.97))
    fig.tight_layout(rect=(0, 0, 1, 0.945))
    return fig


#: At most this many channels of a stream are drawn (one panel each).
AROUND_GO_PANELS = 4


def draw_around_go(aligned: pd.DataFrame, release_t: list[float], title: str) -> Figure:
    """One stream of an XDF recording around Go (``app.analysis.xdf.around_go`` rows of one
    participant and stream): a panel per channel, a line per trial coloured by θ origin, the mean of
    the completed trials (black, on a common grid), Go at 0 and the median release time."""
    channels = list(dict.fromkeys(aligned["channel"]))[:AROUND_GO_PANELS]
    fig, axes = plt.subplots(len(channels), 1, figsize=(7.0, 2.4 * len(channels) + 0.6), sharex=True,
                             squeeze=False)
    for ax, channel in zip(axes[:, 0], channels, strict=True):
        mine = aligned[aligned["channel"] == channel]
        for (_, origin), trial in mine.groupby(["trial_index", "origin"]):
            colour = ORIGIN_STYLE.get(origin, ("tab:gray",))[0]
            ax.plot(trial["t"], trial["value"], color=colour, linewidth=0.8, alpha=0.6)
        completed = mine[mine["outcome"] == "completed"]
        if not completed.empty:
            grid = np.linspace(mine["t"].min(), mine["t"].max(), 200)
            mean = np.nanmean([np.interp(grid, trial["t"], trial["value"], left=np.nan, right=np.nan)
                               for _, trial in completed.groupby("trial_index")], axis=0)
            ax.plot(grid, mean, color="black", linewidth=1.8,
                    label=f"mean of {completed['trial_index'].nunique()} completed trials")
        ax.axvline(0.0, color="black", linewidth=0.8)
        if release_t:
            ax.axvline(float(np.median(release_t)), color="tab:gray", linestyle="--", linewidth=0.8,
                       label="release (median)")
        ax.set_ylabel(channel, fontsize=9)
        ax.grid(alpha=0.3)
    for origin, (colour, _, label) in ORIGIN_STYLE.items():
        if (aligned["origin"] == origin).any():
            axes[0, 0].plot([], [], color=colour, label=label)
    axes[0, 0].legend(fontsize=7, loc="upper left")
    axes[-1, 0].set_xlabel("time since Go [s]")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig

"""Figures: Fig. 3 of the paper (mean distance to the target, 95 % CI, and success rate, by
interaction; the oracle curve thin) and the pilot's validation scores and power."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from app.learning.paper_population import PAPER_POPULATION
from app.learning.pilot import ALPHAS, PilotReport
from app.learning.simulated_study import ConditionSummary, InteractionSummary


def draw_figure3(results: Sequence[tuple[ConditionSummary, list[InteractionSummary]]],
                 path: Path) -> Path:
    """Draw both panels of Fig. 3 for ``results`` (one entry per condition) to the PNG ``path``."""
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8.0, 7.0), sharex=True)
    methods = sorted({(s.acquisition, s.q) for s, _ in results})
    tab10 = plt.get_cmap("tab10")  # ten listed colours: tab10(i) is the i-th
    colours = {method: tab10(i) for i, method in enumerate(methods)}
    for summary, rows in results:
        x = [r.interaction for r in rows]
        mean = [r.mean_distance for r in rows]
        err = [[r.mean_distance - r.ci_low for r in rows],
               [r.ci_high - r.mean_distance for r in rows]]
        # one colour per method, solid without noise, dashed with; the baseline dotted
        style = ":" if summary.acquisition == "sobol" else "-" if summary.noise == 0 else "--"
        colour = colours[(summary.acquisition, summary.q)]
        top.errorbar(x, mean, yerr=err, capsize=2, linestyle=style, linewidth=1.2, color=colour,
                     elinewidth=0.8, label=f"{summary.condition} (N={summary.trials})")
        top.plot(x, [r.mean_oracle_distance for r in rows], linestyle=style, linewidth=0.6,
                 color=colour, alpha=0.7)
        bottom.plot(x, [r.success_rate for r in rows], linestyle=style, linewidth=1.2,
                    color=colour)
    top.set_ylabel("mean distance to target u(θ*)")
    top.set_title("Simulated task (Sect. IV): mean distance of θ* (95 % CI); thin: best shown")
    top.legend(fontsize=8, ncol=2)
    top.grid(alpha=0.3)
    bottom.set_ylabel("success rate (u(θ*) < 0.1)")
    bottom.set_xlabel("interaction")
    bottom.set_ylim(0.0, 1.0)
    bottom.grid(alpha=0.3)
    return _save(fig, path, dpi=90)


def draw_pilot(report: PilotReport, path: Path) -> Path:
    """Validation scores (left) and the sign test's power against participants (right)."""
    fig, (left, right) = plt.subplots(1, 2, figsize=(9.0, 3.6))
    labels = list(report.score_distribution)
    left.bar(labels, list(report.score_distribution.values()), color="tab:blue")
    left.set_xlabel("validation score (θ* preferred)")
    left.set_ylabel("share of participants")
    spread = report.config.spread
    optima = ("uniform optima" if spread is None else "optima of Tables II–III"
              if spread == PAPER_POPULATION else f"optima spread {spread:g}")
    left.set_title(f"{report.config.studies} studies × {report.config.scenarios} × "
                   f"{report.config.participants} participants, σ = {report.config.noise:g}, "
                   f"{optima}", fontsize=9)
    for alpha, colour in zip(ALPHAS, ("tab:green", "tab:red"), strict=True):
        points = [p for p in report.power_curve if p.alpha == alpha]
        n = [report.config.scenarios * p.participants_per_scenario for p in points]
        power = [p.power for p in points]
        err = [[p.power - p.ci_low for p in points], [p.ci_high - p.power for p in points]]
        right.errorbar(n, power, yerr=err, capsize=2, color=colour, marker="o", markersize=3,
                       label=f"α = {alpha:g}")
    right.axhline(0.8, color="grey", linewidth=0.8, linestyle=":")
    right.set_xlabel("participants in all (sign test N)")
    right.set_ylabel("power (95 % CI)")
    right.set_ylim(0.0, 1.02)
    right.legend(fontsize=8)
    right.grid(alpha=0.3)
    return _save(fig, path, dpi=80)


def _save(fig: plt.Figure, path: Path, dpi: int) -> Path:
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path

"""Fig. 3 of the paper: mean distance to the target (95 % CI) and success rate, by interaction."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from app.learning.study import ConditionSummary, InteractionSummary


def draw_figure3(results: Sequence[tuple[ConditionSummary, list[InteractionSummary]]],
                 path: Path) -> Path:
    """Draw both panels of Fig. 3 for ``results`` (one entry per condition) to the PNG ``path``."""
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8.0, 7.0), sharex=True)
    methods = sorted({(s.acquisition, s.q) for s, _ in results})
    colours = dict(zip(methods, plt.get_cmap("tab10").colors, strict=False))
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
        bottom.plot(x, [r.success_rate for r in rows], linestyle=style, linewidth=1.2,
                    color=colour)
    top.set_ylabel("mean distance to target u(θ*)")
    top.set_title("Simulated task (Sect. IV): mean distance, 95 % CI")
    top.legend(fontsize=8, ncol=2)
    top.grid(alpha=0.3)
    bottom.set_ylabel("success rate (u(θ*) < 0.1)")
    bottom.set_xlabel("interaction")
    bottom.set_ylim(0.0, 1.0)
    bottom.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path

"""Fig. 4 of the paper for one handover: human and robot distance to the handover point, each
normalised by its distance at the start, against time."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def normalised_distance(positions: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """‖p(t) − H‖ / ‖p(0) − H‖ (the normalisation of Fig. 4)."""
    distance = np.linalg.norm(positions - goal, axis=1)
    return distance / max(float(distance[0]), 1e-9)


def plot_trial(samples: dict[str, np.ndarray], goal: np.ndarray, path: Path, title: str = "") -> None:
    """Write a Fig. 4 style PNG: the human in red, the robot in blue (as in the paper)."""
    t = samples["t"]
    has_hand = np.all(np.isfinite(samples["hand"]), axis=1)
    fig, ax = plt.subplots(figsize=(6.0, 3.2), dpi=120)
    ax.plot(t[has_hand], normalised_distance(samples["hand"][has_hand], goal), color="tab:red",
            label="human hand")
    ax.plot(t, normalised_distance(samples["measured"], goal), color="tab:blue", label="robot TCP")
    ax.set_xlabel("time since Go [s]")
    ax.set_ylabel("distance to handover point\n(normalised to start)")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)

"""The data of Fig. 4: human and robot distance to the handover point H during the validation trials,
each normalised by its distance at the start of the trial (Sect. VI-C, Fig. 4 caption)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from app.analysis.tables import study_configs
from robot_io.plot import normalised_distance

HAND = ["hand_x", "hand_y", "hand_z"]
ROBOT = ["measured_x", "measured_y", "measured_z"]  # the TCP as read back from the arm


def _normalised(positions: np.ndarray, goal: np.ndarray, fresh: np.ndarray | None = None
                ) -> np.ndarray:
    """Normalised distance where the position is known and ``fresh`` (NaN elsewhere)."""
    known = np.all(np.isfinite(positions), axis=1)
    if fresh is not None:
        known &= fresh
    out = np.full(len(positions), np.nan)
    if known.any():
        out[known] = normalised_distance(positions[known], goal)
    return out


def validation_distances(participants: pd.DataFrame, trials: pd.DataFrame,
                         samples: pd.DataFrame) -> pd.DataFrame:
    """One row per control cycle of each completed validation trial: ``t`` [s since Go], and the
    ``human`` and ``robot`` distances to H over their distances at the start (1 at the start, 0 at H).
    The tracker is slower than the control loop: ``human`` is given on the cycles that received a new
    hand sample and is NaN on those that held the previous one.

    H is each participant's ``controller.scene.handover_point``. ``origin`` tells the learned θ*
    (``best``) from the Sobol reference (``sobol``).
    """
    goals = {code: config.controller.scene.point("handover_point")
             for code, config in study_configs(participants).items()}
    done = trials[(trials["phase"] == "validation") & (trials["outcome"] == "completed")]
    keys = done[["participant", "trial_index", "batch", "origin"]]
    rows = samples.merge(keys, on=["participant", "trial_index"])
    parts = []
    for (code, _), trial in rows.groupby(["participant", "trial_index"], sort=True):
        goal = goals[code]
        hand_t = trial["hand_t"].to_numpy(float)
        new_hand_sample = np.r_[True, hand_t[1:] != hand_t[:-1]]
        parts.append(trial[["participant", "trial_index", "batch", "origin", "t"]].assign(
            human=_normalised(trial[HAND].to_numpy(float), goal, new_hand_sample),
            robot=_normalised(trial[ROBOT].to_numpy(float), goal)))
    columns = ["participant", "trial_index", "batch", "origin", "t", "human", "robot"]
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=columns)

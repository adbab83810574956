"""Per-cycle records of a handover: one row per control cycle in a preallocated float array."""

from __future__ import annotations

import numpy as np

#: Column groups of a trial sample row, in order: name, width (3-vectors are x, y, z), meaning.
COLUMNS: tuple[tuple[str, int, str], ...] = (
    ("t", 1, "trial time since Go [s]"),
    ("s", 1, "DMP phase s, eq. (3)"),
    ("tau", 1, "τ = τ0(1 + C_t), eq. (5) [s]"),
    ("x", 3, "DMP position [m]"),
    ("xd", 3, "DMP velocity [m/s]"),
    ("hand", 3, "latest valid hand sample [m]"),
    ("hand_t", 1, "time stamp of that hand sample [s]"),
    ("d", 1, "hand distance to the handover point, eq. (6) [m]"),
    ("d_filtered", 1, "filtered distance d̃, eq. (7) [m]"),
    ("d_rate", 1, "its rate d̃̇, eq. (7) [m/s]"),
    ("sigma_d", 1, "σ_d(d̃/d0), eq. (10)"),
    ("sigma_j", 1, "σ_j(d̃̇), eq. (10)"),
    ("c_t", 1, "temporal coupling C_t, eq. (8)"),
    ("c_s", 3, "spatial coupling C_s, eq. (9)"),
    ("commanded", 3, "target sent to the arm after the safety limiter [m]"),
    ("measured", 3, "TCP position read from the arm [m]"),
    ("q", 6, "joint angle read from the arm [rad] (joints 0 base, 1 shoulder, 2 elbow, 3–5 wrist 1–3; "
             "empty for an arm that does not report them: the mock)"),
    ("limited", 1, "safety limiter flags: 1 acceleration, 2 speed, 4 workspace"),
    ("stage", 1, "stage of the handover cycle: 1 reach, 2 hold, 3 released (robot_io.control.stages)"),
    ("force", 3, "force at the TCP while holding [N] (empty during the reach)"),
    ("pull", 1, "baseline-subtracted, filtered pull ‖F̃ − F₀‖ while armed [N] (robot_io.control.release)"),
    ("compute_s", 1, "compute time of the cycle [s]"),
    ("lateness_s", 1, "how late the cycle started [s]"),
)

SLICES: dict[str, slice] = {}
_start = 0
for _name, _width, _ in COLUMNS:
    SLICES[_name] = slice(_start, _start + _width)
    _start += _width
WIDTH = _start


class TrialRecorder:
    """Rows are written in place into a (capacity × WIDTH) array; :meth:`columns` gives named views."""

    def __init__(self, capacity: int) -> None:
        self._rows = np.full((max(capacity, 1), WIDTH), np.nan)
        self.count = 0

    def next_row(self) -> np.ndarray:
        """The row for this cycle (grows the buffer when full)."""
        if self.count == len(self._rows):
            self._rows = np.vstack([self._rows, np.full_like(self._rows, np.nan)])
        row = self._rows[self.count]
        self.count += 1
        return row

    def finish(self) -> None:
        """The loop has written its last row and now stops the arm (nothing to do in memory)."""

    def columns(self) -> dict[str, np.ndarray]:
        """Named columns of the rows written so far; a group of width w > 1 has shape (n, w)."""
        return self._named(self._rows[: self.count])

    def view(self, stride: int = 1) -> dict[str, np.ndarray]:
        """A copy of every ``stride``-th finished row, safe to call from another thread while the
        loop writes: the row being filled (the last one) is left out, and a buffer that grows
        meanwhile is replaced, not changed, so the reference taken here stays consistent."""
        rows, count = self._rows, self.count
        return self._named(rows[: max(count - 1, 0): stride].copy())

    @staticmethod
    def _named(rows: np.ndarray) -> dict[str, np.ndarray]:
        return {name: rows[:, SLICES[name]].squeeze(axis=1) if width == 1 else rows[:, SLICES[name]]
                for name, width, _ in COLUMNS}

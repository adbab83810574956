"""Per-cycle samples from the rig process to the application, through shared memory.

The application creates one block per rig process: a header row ``[rows written, trial index,
finished]`` (finished: 1 once the loop has written its last row and stops the arm) and
``capacity`` sample rows of :data:`robot_io.control.recorder.COLUMNS`. The rig's :class:`StreamRecorder`
writes each row in place, then bumps the count, so a reader never sees a row before it is written and
reads cost the loop nothing. If the rig process dies, what it wrote is still there.
"""

from __future__ import annotations

from multiprocessing import shared_memory

import numpy as np

from robot_io.config import ControllerConfig
from robot_io.control.recorder import WIDTH, TrialRecorder

#: Extra seconds of rows beyond the longest possible trial.
MARGIN_S = 2.0


def capacity_for(config: ControllerConfig, rate_hz: int) -> int:
    """Rows for the longest trial: reach timeout + hold timeout + linger + margin."""
    seconds = (config.loop.timeout_s + config.release.timeout_s + config.cycle.release_linger_s
               + MARGIN_S)
    return int(seconds * rate_hz)


class SampleStream:
    """A shared block of sample rows. ``create=True`` in the application, False in the rig."""

    def __init__(self, capacity: int, name: str | None = None) -> None:
        size = (capacity + 1) * WIDTH * 8
        # the creator (the application) unlinks it; its resource tracker, which a spawned rig
        # shares, unlinks it if the application is killed
        self.shm = shared_memory.SharedMemory(name=name, create=name is None, size=size)
        array = np.ndarray((capacity + 1, WIDTH), dtype=np.float64, buffer=self.shm.buf)
        self.header, self.rows = array[0], array[1:]
        self.name = self.shm.name

    @property
    def trial_index(self) -> int:
        return int(self.header[1])

    def columns(self) -> dict[str, np.ndarray]:
        """A copy of every row written for the current trial."""
        count = int(self.header[0])
        return TrialRecorder._named(self.rows[:count].copy())

    def view(self, stride: int = 1) -> dict[str, np.ndarray]:
        """Every ``stride``-th finished row (the row being written is left out)."""
        count = int(self.header[0])
        return TrialRecorder._named(self.rows[: max(count - 1, 0): stride].copy())

    @property
    def count(self) -> int:
        return int(self.header[0])

    @property
    def finished(self) -> bool:
        """The trial's loop has written its last row (it is stopping the arm, or has stopped it)."""
        return bool(self.header[2] == 1.0)

    def close(self, unlink: bool = False) -> None:
        """Release the block; a closed stream reads as empty (a screen may still ask)."""
        self.header, self.rows = np.array([0.0, -1.0, 0.0]), np.empty((0, WIDTH))
        self.shm.close()
        if unlink:
            self.shm.unlink()


class StreamRecorder(TrialRecorder):
    """The rig's recorder for one trial, writing into a :class:`SampleStream`."""

    def __init__(self, stream: SampleStream, trial_index: int) -> None:
        self._rows, self._header = stream.rows, stream.header
        self._header[0] = 0
        self._header[1] = trial_index
        self._header[2] = 0.0
        self._rows[:] = np.nan
        self.count = 0

    def next_row(self) -> np.ndarray:
        """The row for this cycle; when the block is full the last row is overwritten."""
        if self.count == len(self._rows):
            return self._rows[-1]
        row = self._rows[self.count]
        self.count += 1
        self._header[0] = self.count
        return row

    def finish(self) -> None:
        self._header[2] = 1.0

"""Per-cycle samples from the rig process to the application, through shared memory.

The application creates one block per rig process: a header row ``[rows written, trial index,
finished]`` (finished: 1 once the loop has written its last row and stops the arm) and
``capacity`` sample rows of :data:`robot_io.control.recorder.COLUMNS`. The rig's :class:`StreamRecorder`
writes each row in place, then bumps the count, so a reader never sees a row before it is written and
reads cost the loop nothing. If the rig process dies, what it wrote is still there.

Lifetime (docs/architecture.md, "Shared objects and their lifetimes"): in each process the block is
mapped by one :class:`SampleStream` and unmapped by its :meth:`SampleStream.close` alone. Every read
in that process goes through the stream's methods, which copy under the stream's lock, and
:meth:`~SampleStream.close` takes the same lock: an unmapping never lands in the middle of a copy
(numpy does not pin the mapping: a copy from an unmapped block is a segmentation fault), and a read
after the release reads an empty stream.
"""

from __future__ import annotations

import threading
from multiprocessing import shared_memory

import numpy as np

from robot_io.config import ControllerConfig
from robot_io.control.recorder import WIDTH, TrialRecorder

#: Extra seconds of rows beyond the longest possible trial.
MARGIN_S = 2.0
#: The header of a released stream: no rows, no trial, not finished.
_RELEASED_HEADER = (0.0, -1.0, 0.0)


def capacity_for(config: ControllerConfig, rate_hz: int) -> int:
    """Rows for the longest trial: reach timeout + hold timeout + linger + margin."""
    seconds = (config.loop.timeout_s + config.release.timeout_s + config.cycle.release_linger_s
               + MARGIN_S)
    return int(seconds * rate_hz)


class SampleStream:
    """A shared block of sample rows. ``name=None`` creates it (the application), a name maps the
    block the application created (the rig). Any thread of the process may read; one releases it
    (:meth:`close`)."""

    def __init__(self, capacity: int, name: str | None = None) -> None:
        size = (capacity + 1) * WIDTH * 8
        # the creator (the application) unlinks it; its resource tracker, which a spawned rig
        # shares, unlinks it if the application is killed
        self._shm: shared_memory.SharedMemory | None = shared_memory.SharedMemory(
            name=name, create=name is None, size=size)
        array = np.ndarray((capacity + 1, WIDTH), dtype=np.float64, buffer=self._shm.buf)
        self._header, self._rows = array[0], array[1:]
        self.name = self._shm.name
        self.capacity = capacity
        self._lock = threading.Lock()  # held over every read of the block and over its release

    @property
    def released(self) -> bool:
        return self._shm is None

    @property
    def trial_index(self) -> int:
        with self._lock:
            return int(self._header[1])

    @property
    def count(self) -> int:
        with self._lock:
            return int(self._header[0])

    @property
    def finished(self) -> bool:
        """The trial's loop has written its last row (it is stopping the arm, or has stopped it)."""
        with self._lock:
            return bool(self._header[2] == 1.0)

    def columns(self) -> dict[str, np.ndarray]:
        """A copy of every row written for the current trial."""
        with self._lock:
            rows = self._rows[: int(self._header[0])].copy()
        return TrialRecorder._named(rows)

    def view(self, stride: int = 1) -> dict[str, np.ndarray]:
        """Every ``stride``-th finished row (the row being written is left out)."""
        with self._lock:
            rows = self._rows[: max(int(self._header[0]) - 1, 0): stride].copy()
        return TrialRecorder._named(rows)

    def rows_of(self, trial_index: int, start: int, finished_only: bool = True) -> np.ndarray:
        """A copy of trial ``trial_index``'s rows from ``start`` on: the finished ones (the last
        counted row may still be being written), all of them once the trial has finished, or all
        counted ones with ``finished_only=False``. Empty if another trial streams now."""
        with self._lock:
            count, trial, finished = self._header[:3]
            if int(trial) != trial_index:
                return np.empty((0, WIDTH))
            end = int(count) if finished == 1.0 or not finished_only else int(count) - 1
            return self._rows[start:max(end, start)].copy()

    def close(self, unlink: bool = False) -> None:
        """Release the block (``unlink``: and remove it; the creator does); reads from now on see
        an empty stream. Waits for a read under way; a second call does nothing."""
        with self._lock:
            shm, self._shm = self._shm, None
            if shm is None:
                return
            self._header, self._rows = np.array(_RELEASED_HEADER), np.empty((0, WIDTH))
            shm.close()
            if unlink:
                shm.unlink()


class StreamRecorder(TrialRecorder):
    """The rig's recorder for one trial, writing into a :class:`SampleStream` (on the rig's loop
    thread, which also releases the stream when the rig exits)."""

    def __init__(self, stream: SampleStream, trial_index: int) -> None:
        self._rows, self._header = stream._rows, stream._header
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

"""Replaying a stored trial in the dashboard's live view, at 1× or slower, while no trial runs.

The rows come from the store through :meth:`SessionRunner.trial_rows` (the recorder's own columns);
a frame at wall time w after the start draws every row with trial time t ≤ t0 + speed · w, so the
robot, the hand and the coupling plots move as they did, ``speed`` times as fast. A trial that starts
ends the replay (the live view belongs to the running trial).

The replay's thread draws only through ``draw`` and ``on_end``, which its page guards (the page's
lock: nothing is drawn for a page that has gone); the page ends it with :meth:`Replay.stop`, which
waits for the thread, before the page or the server is closed.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

#: Replay speeds the dashboard offers (1× is real time).
SPEEDS = {"1×": 1.0, "0.5×": 0.5, "0.25×": 0.25}
#: Frames per second of a replay.
FPS = 20.0


class Replay:
    """One replay drawn frame by frame with ``draw`` (a live view's, :meth:`LiveView.draw`), on its
    own thread; ``busy`` says when a trial runs, ``on_end`` is told why the replay ended."""

    def __init__(self, draw: Callable[[dict[str, np.ndarray]], None], rows: dict[str, np.ndarray],
                 speed: float, busy: Callable[[], bool], on_end: Callable[[str], None]) -> None:
        if not 0.0 < speed <= 1.0:
            raise ValueError(f"speed = {speed} must lie in (0, 1] (1× or slower)")
        keep = np.isfinite(rows["t"])
        self._draw, self.speed = draw, speed
        self.rows = {name: values[keep] for name, values in rows.items()}
        self._busy, self._on_end = busy, on_end
        self._cancel = threading.Event()
        self.frames = 0
        self._thread = threading.Thread(target=self._run, name="replay", daemon=True)
        self._thread.start()

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def cancel(self) -> None:
        """End the replay at its next frame (from any thread; returns at once)."""
        self._cancel.set()

    def stop(self) -> None:
        """End the replay and wait until its thread has ended (it draws nothing after this)."""
        self._cancel.set()
        self._thread.join()

    def _run(self) -> None:
        t = self.rows["t"]
        t0, began = float(np.nanmin(t)), time.monotonic()
        end = "replay finished"
        count = 0
        while count < len(t):
            if self._cancel.is_set():
                end = "replay stopped"
                break
            if self._busy():
                end = "replay ended: a trial started"
                break
            now = t0 + self.speed * (time.monotonic() - began)
            count = max(int(np.searchsorted(t, now, side="right")), 2)
            self._draw({name: values[:count] for name, values in self.rows.items()})
            self.frames += 1
            if count < len(t):
                self._cancel.wait(1.0 / FPS)
        self._on_end(end)

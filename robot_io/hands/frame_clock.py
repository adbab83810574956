"""A tracker frame's instant on this machine's clock, from the frame's own camera time.

A tracker (Vicon, OptiTrack Motive) numbers or time-stamps its frames on its cameras' clock. A
frame is seen here later than it was exposed by a delay that is never negative (the tracker's
pipeline less the latency it reports, the network, this process's scheduling) and is least for the
promptest frame. So the offset of the two clocks is the least (seen − camera time) over the frames
of a recent window (a sliding minimum), and each frame is stamped at its camera time plus that
offset: never later than it was seen, and spaced as the cameras exposed the frames however late or
bunched they arrive. Stamped when seen, frames that arrive together after a stall would carry a
moving hand's tenth of a second within a millisecond, and be refused as jumps.
"""

from __future__ import annotations

import collections

#: The span over which the smallest clock offset is taken [s]: long enough to hold a frame seen
#: without delay (and a stall shorter than it keeps its frames' spacing), short enough that the
#: cameras' clock drifts from this one by microseconds in it.
FRAME_CLOCK_WINDOW_S = 1.0


class FrameClock:
    """Camera time [s] → ``time.monotonic``: camera time plus the smallest (seen − camera time)
    over the frames seen in the last ``window_s``. A camera time that does not advance starts anew
    (the tracker restarted, or replays): that frame is stamped when seen."""

    def __init__(self, window_s: float = FRAME_CLOCK_WINDOW_S) -> None:
        self.window_s = window_s
        #: (seen, offset) of the frames that can still be the window's least, offsets rising
        self._offsets: collections.deque[tuple[float, float]] = collections.deque()
        self._last: float | None = None

    def reset(self) -> None:
        """Forget every offset: the next frame is stamped when seen."""
        self._offsets.clear()
        self._last = None

    def stamp(self, camera_s: float, seen: float) -> float:
        """The instant on ``time.monotonic`` of the frame of camera time ``camera_s``, seen (less
        any latency the tracker reports) at ``seen``."""
        if self._last is not None and not camera_s > self._last:
            self._offsets.clear()
        self._last = camera_s
        offset = seen - camera_s
        while self._offsets and self._offsets[-1][1] >= offset:  # a sliding-window minimum
            self._offsets.pop()
        self._offsets.append((seen, offset))
        while self._offsets[0][0] < seen - self.window_s:
            self._offsets.popleft()
        return min(seen, camera_s + self._offsets[0][1])  # (min: never later by a rounding)

"""A hand source reading a Lab Streaming Layer stream (Vicon, OptiTrack and most mocap systems publish
one). The stream's channels ``lsl_channels`` hold the marker's x, y, z in tracker units."""

from __future__ import annotations

import logging

import pylsl

from robot_io.config import HandSourceConfig
from robot_io.errors import HandSourceError
from robot_io.frame import FrameTransform
from robot_io.tracked_hand import TrackedHand

log = logging.getLogger(__name__)


class LSLHand(TrackedHand):
    """Resolves the stream by type (and name), then pulls samples in a thread."""

    def __init__(self, config: HandSourceConfig, transform: FrameTransform) -> None:
        super().__init__(transform)
        self.channels = list(config.lsl_channels)
        streams = pylsl.resolve_byprop("type", config.lsl_stream_type,
                                       timeout=config.resolve_timeout_s)
        if config.lsl_stream_name is not None:
            streams = [s for s in streams if s.name() == config.lsl_stream_name]
        if not streams:
            raise HandSourceError(
                f"no LSL stream of type {config.lsl_stream_type!r}"
                + (f" named {config.lsl_stream_name!r}" if config.lsl_stream_name else "")
                + f" found within resolve_timeout_s = {config.resolve_timeout_s} s")
        info = streams[0]
        if max(self.channels) >= info.channel_count():
            raise HandSourceError(f"hand_source.lsl_channels = {tuple(self.channels)} but stream "
                                  f"{info.name()!r} has {info.channel_count()} channels")
        self.name, self.nominal_rate_hz = info.name(), info.nominal_srate()
        self.inlet = pylsl.StreamInlet(info, max_buflen=1, processing_flags=pylsl.proc_clocksync)
        self.inlet.open_stream(timeout=config.resolve_timeout_s)
        log.info("LSL hand source: stream %r at %g Hz", self.name, self.nominal_rate_hz)
        self.start()

    def receive_once(self) -> None:
        # Wait for one sample (pull_chunk waits out its whole timeout, which would age every
        # sample), then take whatever else has queued without waiting: a backlog (the stream's first
        # ~0.6 s arrive at once while clock sync starts, or a network stall) is put in one wake.
        # One sample per wake drained it at one sample per GIL turn (~2 ms) while the control loop
        # ran, so the newest sample stayed hundreds of ms old and a trial could end tracker_lost.
        # proc_clocksync maps the outlet's time stamps onto pylsl.local_clock(), which on Linux is
        # the monotonic clock that time.monotonic() reads.
        sample, stamp = self.inlet.pull_sample(timeout=0.1)
        if sample is None:
            return
        samples, stamps = self.inlet.pull_chunk(timeout=0.0)
        for queued, queued_stamp in zip([sample, *samples], [stamp, *stamps], strict=True):
            self.put(queued_stamp, [queued[c] for c in self.channels])

    def close(self) -> None:
        super().close()
        self.inlet.close_stream()

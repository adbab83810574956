"""A stand-in for a lab's eye tracker on LSL: a pupil diameter stream that dilates each time the robot
starts to move.

It listens to the study's robot stream like any other LSL client: a trial's first sample is its Go
(the stream runs from Go on), and from there its diameter follows a dilation that begins
:data:`ONSET_S` later (the pupil's response latency) and is over :data:`END_S` after it. Like a
real tracker its camera captures at a fixed rate (:data:`RATE_HZ`, capture times on a regular grid,
each sample's time stamp) and it delivers each sample :data:`LATENCY_S` after its capture, or later
when this process is late: by then the robot's samples of that moment have arrived, however late the
machine's load made them, so every value follows the robot's actual start. ``handover report
--xdf`` must find the dilation at the same time after Go in every trial.

The grid matters: pyxdf, as the report loads a recording, dejitters a stream of nominal rate (it
replaces the time stamps by a line fitted through them), which is exact for a camera's regular
captures. Captures stamped when a loaded Python thread happened to run (as here before) were
irregular, and dejittering moved them by up to 0.57 s: the dilation came 0.05–0.44 s early
against Go in `make soak` and when two suites shared two cores.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import pylsl

from support.waiting import CEILING_S

RATE_HZ = 60.0
BASELINE_MM = 3.2
DILATION_MM = 0.6
ONSET_S = 0.3  # the dilation begins this long after the robot starts
LATENCY_S = 1.0  # a sample is delivered this long after its capture time
END_S = 1.2  # and is over this long after it (the next trial's Go comes 2.7 s or more after this one)


def diameter(since_start: float, dilation: float = DILATION_MM) -> float:
    """The stand-in's pupil diameter [mm] ``since_start`` seconds after the robot started."""
    if not ONSET_S <= since_start <= END_S:
        return BASELINE_MM
    return BASELINE_MM + dilation * math.sin(math.pi * (since_start - ONSET_S) / (END_S - ONSET_S))


class PupilTracker:
    """Publishes stream ``name`` (type ``Gaze``, one channel ``pupil_diameter_mm``) at
    :data:`RATE_HZ` while listening to the robot stream ``robot``. ``spread``: each trial's
    dilation is DILATION_MM × (1 + spread × a normal draw); ``noise_mm``: the standard deviation of
    a measurement noise (both 0 in tests: exact values; benchmarks/lsl_outlets.py draws the docs'
    figure with some)."""

    def __init__(self, name: str, robot: str, spread: float = 0.0, noise_mm: float = 0.0,
                 seed: int = 0) -> None:
        self._rng, self._spread, self._noise = np.random.default_rng(seed), spread, noise_mm
        self.dilations: list[float] = []  # each trial's
        info = pylsl.StreamInfo(name, "Gaze", 1, RATE_HZ, pylsl.cf_float32, f"{name}-eyetracker")
        info.desc().append_child("channels").append_child("channel").append_child_value(
            "label", "pupil_diameter_mm")
        self.outlet = pylsl.StreamOutlet(info)
        found = pylsl.resolve_byprop("name", robot, 1, CEILING_S)
        assert found, f"no robot stream {robot!r} within {CEILING_S} s"
        self.inlet = pylsl.StreamInlet(found[0])
        self.inlet.open_stream(CEILING_S)
        self.trial, self.starts = 0.0, []  # the robot's latest trial; when each trial started
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name="pupil-tracker", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        period = 1.0 / RATE_HZ
        captured = pylsl.local_clock() - LATENCY_S  # the first capture, delivered now
        # delivery LATENCY_S after each capture: pacing, as a tracker's own clock does
        while not self._stopping.wait(max(captured + LATENCY_S - pylsl.local_clock(), 0.0)):
            samples, stamps = self.inlet.pull_chunk(timeout=0.0)
            for sample, stamp in zip(samples, stamps, strict=True):
                if sample[0] != self.trial:  # channel 0: the trial index
                    self.trial = sample[0]
                    self.starts.append(stamp)
                    self.dilations.append(DILATION_MM * (1.0 + self._spread * self._rng.standard_normal()))
            started = [i for i, start in enumerate(self.starts) if start <= captured]
            value = (diameter(captured - self.starts[started[-1]], self.dilations[started[-1]])
                     if started else BASELINE_MM)
            value += self._noise * self._rng.standard_normal() if self._noise else 0.0
            self.outlet.push_sample([value], captured)
            captured += period

    def close(self) -> None:
        self._stopping.set()
        self._thread.join()
        self.inlet.close_stream()

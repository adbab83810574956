"""A simulated participant's hand for the paper's two scenarios (Sect. V-A, Fig. 1).

*Straightforward*: after a reaction delay, a minimum-jerk reach from the start A to the handover point H.
*Perturbed*: A → box B (about 25 cm from H), pause to grasp, → place C, pause to put it down, → H.
Reaction delay, hand speed and pauses are drawn per trial from a seeded generator; the trajectory is
sampled at the tracker rate with optional Gaussian noise and dropped samples.
"""

from __future__ import annotations

import itertools
from enum import StrEnum

import numpy as np

from robot_io.errors import ConfigError
from robot_io.hands.hand import HandSample
from robot_io.hands.profile import HandProfile
from robot_io.minimum_jerk import minimum_jerk
from robot_io.scene import SceneConfig


class Scenario(StrEnum):
    STRAIGHTFORWARD = "straightforward"
    PERTURBED = "perturbed"

    @classmethod
    def parse(cls, text: str) -> Scenario:
        try:
            return cls(text)
        except ValueError:
            allowed = ", ".join(s.value for s in cls)
            raise ConfigError(f"scenario = {text!r} is not one of: {allowed}") from None


#: Waypoints of each scenario (names of SceneConfig fields); a pause is made at every inner waypoint.
WAYPOINTS: dict[Scenario, tuple[str, ...]] = {
    Scenario.STRAIGHTFORWARD: ("hand_start", "handover_point"),
    Scenario.PERTURBED: ("hand_start", "box", "place", "handover_point"),
}


class SimulatedHand:
    """A seeded hand trajectory, served as a tracker would: ``latest(now)`` is the newest sample whose
    time stamp is ≤ now; lost samples are skipped, so the newest one can be older.

    ``hold_s`` is how long the hand stays at H after arriving (the trajectory then ends: a source that
    stops delivering). ``segments`` lists (start time, end time, from, to) of each reach.
    """

    def __init__(self, scenario: Scenario, scene: SceneConfig, profile: HandProfile, seed: int,
                 hold_s: float = 60.0) -> None:
        rng = np.random.default_rng(seed)
        self.scenario = scenario
        self.reaction_delay = float(rng.uniform(*profile.reaction_delay_s))
        speed = float(rng.uniform(*profile.mean_speed_mps))
        points = [scene.point(name) for name in WAYPOINTS[scenario]]
        self.segments: list[tuple[float, float, np.ndarray, np.ndarray]] = []
        t = self.reaction_delay
        for i, (a, b) in enumerate(itertools.pairwise(points)):
            if i > 0:
                t += float(rng.uniform(*profile.pause_s))
            duration = float(np.linalg.norm(b - a)) / speed
            self.segments.append((t, t + duration, a, b))
            t += duration
        self.arrival_time = t
        period = 1.0 / profile.tracker_rate_hz
        self.start = points[0]
        self.times = np.arange(0.0, t + hold_s, period)
        self.positions = self._positions(self.times)
        if profile.noise_std_m > 0:
            self.positions += rng.normal(0.0, profile.noise_std_m, self.positions.shape)
        self.delivered = rng.random(len(self.times)) >= profile.dropout_rate
        self.delivered[0] = True
        self.period = period

    def _positions(self, times: np.ndarray) -> np.ndarray:
        positions = np.tile(self.start, (len(times), 1))
        for t0, t1, a, b in self.segments:
            after = times >= t0
            positions[after] = minimum_jerk(a, b, t1 - t0, times[after] - t0)[0]
        return positions

    def position_at(self, t: float) -> np.ndarray:
        """The noise-free hand position at time ``t`` (for tests and plots)."""
        return self._positions(np.array([t]))[0]

    def latest(self, now: float) -> HandSample | None:
        if now < 0:
            return None
        index = min(int(np.floor(now / self.period + 1e-9)), len(self.times) - 1)
        while index >= 0 and not self.delivered[index]:
            index -= 1
        if index < 0:
            return None
        return HandSample(float(self.times[index]), self.positions[index])

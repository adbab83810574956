"""``[hand]``: the participant's hand — the fastest any hand moves, which tracked samples must respect,
and how the simulated participant moves (``robot_io.hands.simulated_hand``)."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, model_validator

from robot_io.bounds import Frozen, in_range
from robot_io.errors import ConfigError

#: Upper bounds of the simulated participant's ranges: a reaction, a hand speed, a pause.
HAND_RANGE_BOUNDS = {"reaction_delay_s": 5.0, "mean_speed_mps": 3.0, "pause_s": 10.0}


#: A minimum-jerk reach's peak speed over its mean speed (15/8).
MINIMUM_JERK_PEAK_OVER_MEAN = 1.875


class HandProfile(Frozen):
    """The participant's hand: the fastest any hand moves, which tracked samples must respect, and
    how the simulated participant moves (each range drawn from uniformly per trial)."""

    max_speed: Annotated[float, in_range(0, 10, "m/s")] = Field(
        3.0, description="the fastest a hand moves [m/s]: a tracked sample farther from the last "
                         "accepted one than this speed allows is a tracker jump, refused as a "
                         "dropout (reach-to-grasp peaks at 1-1.5 m/s; 3 leaves room for a hurry)")

    tracker_rate_hz: Annotated[float, in_range(0, 2000, "Hz")] = Field(
        100.0, description="tracker sample rate (Vicon in the paper; mocap runs at most ~2 kHz)")
    reaction_delay_s: tuple[float, float] = Field((0.15, 0.35), description="delay after Go [s]")
    mean_speed_mps: tuple[float, float] = Field(
        (0.45, 0.65), description="mean hand speed of each reach [m/s] (duration = length/speed)")
    pause_s: tuple[float, float] = Field(
        (0.25, 0.50), description="pause to grasp the box at B and to put it down at C [s]")
    noise_std_m: Annotated[float, in_range(0, 0.1, "m", low_open=False)] = Field(
        0.0, description="tracker noise, std per axis [m]")
    dropout_rate: float = Field(0.0, ge=0, lt=1, description="share of tracker samples lost")
    pull_n: float = Field(15.0, ge=0, le=100, description="pull on the object once grasped [N]; 0: "
                                                         "never takes it (see robot_io.hands.simulated_pull)")
    grasp_delay_s: float = Field(0.5, ge=0, le=10, description="from touching the object to pulling "
                                                               "[s]; longer than [release] baseline_s")

    @model_validator(mode="after")
    def _ranges_ordered(self) -> HandProfile:
        for name in ("reaction_delay_s", "mean_speed_mps", "pause_s"):
            low, high = getattr(self, name)
            if not 0 <= low <= high <= HAND_RANGE_BOUNDS[name]:
                raise ConfigError(f"hand.{name} = ({low}, {high}) must satisfy 0 ≤ low ≤ high ≤ "
                                  f"{HAND_RANGE_BOUNDS[name]:g}")
        if self.mean_speed_mps[0] <= 0:
            raise ConfigError(f"hand.mean_speed_mps = {self.mean_speed_mps} must be > 0")
        peak = MINIMUM_JERK_PEAK_OVER_MEAN * self.mean_speed_mps[1]
        if peak > self.max_speed:
            raise ConfigError(f"hand.mean_speed_mps = {self.mean_speed_mps} makes reaches that peak "
                              f"at {peak:.2f} m/s, beyond hand.max_speed = {self.max_speed:g} m/s: "
                              "the simulated hand's samples would be refused as tracker jumps")
        return self

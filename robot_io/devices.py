"""Opening the configured devices (arm, hand source, gripper) and ``handover check-devices``."""

from __future__ import annotations

import time

import numpy as np

from robot_io.arms.arm import ConnectedArm
from robot_io.config import ControllerConfig
from robot_io.control.loop import TrialRecord
from robot_io.control.trial import make_clock, make_loop
from robot_io.errors import RobotIOError
from robot_io.grippers.gripper import Gripper
from robot_io.hands.frame import FrameTransform
from robot_io.hands.hand import HandSource
from robot_io.hands.simulated_hand import Scenario, SimulatedHand
from robot_io.hands.tracked_hand import PLAUSIBLE_RANGE_M, TrackedHand
from robot_io.theta import Theta


def tracker_transform(config: ControllerConfig) -> FrameTransform:
    source = config.hand_source
    return FrameTransform(np.asarray(source.rotation, dtype=float),
                          np.asarray(source.translation, dtype=float), source.units_to_m)


def open_hand(config: ControllerConfig, scenario: Scenario | None = None, seed: int = 0) -> HandSource:
    """The configured hand source: a tracker's, connected (``[hand_source] kind``, robot_io.hands.config),
    or the simulated participant's, which needs a scenario."""
    if config.hand_source.reader is not None:
        return open_tracked_hand(config)
    if scenario is None:
        raise RobotIOError("hand_source.kind = 'simulated' needs a scenario")
    return SimulatedHand(scenario, config.scene, config.hand, seed)


def open_tracked_hand(config: ControllerConfig) -> TrackedHand:
    """The configured tracker's hand source, connected (``[hand_source]`` names a tracker)."""
    return config.hand_source.open(tracker_transform(config), config.hand.max_speed)


def open_gripper(config: ControllerConfig) -> Gripper:
    """The configured gripper, connected (a Robotiq one also activated, if it was not)."""
    return config.gripper.open(config.controller_host)


def arm_trial(config: ControllerConfig, theta: Theta | None, hand: HandSource,
              arm: ConnectedArm) -> TrialRecord:
    """One real-time handover on a connected arm at its controller's rate (a UR's 125 or 500 Hz)."""
    config = config.model_copy(update={"loop": config.loop.model_copy(update={"rate_hz": arm.rate_hz})})
    return make_loop(config, theta, hand, arm, make_clock(config, realtime=True)).run()


def check_devices(config: ControllerConfig, listen_s: float = 1.0) -> tuple[list[str], bool]:
    """Connect to the configured arm, hand source and gripper; report in plain words; move nothing.
    Returns the report lines and whether everything is usable."""
    lines, arm_ok = config.arm.check(config)
    lines.extend(_check_hand(config, listen_s))

    lines.append(_check_gripper(config))
    return lines, arm_ok and not any("NOT OK" in line for line in lines)


def _check_gripper(config: ControllerConfig) -> str:
    """One line on the gripper: reachable, and a Robotiq's activation, position and fault code
    (read, never activated or moved)."""
    try:
        return f"gripper: {config.gripper.check(config.controller_host)}"
    except RobotIOError as exc:
        return f"gripper: NOT OK — {str(exc).removeprefix('gripper: ')}"


def _check_hand(config: ControllerConfig, listen_s: float) -> list[str]:
    kind = config.hand_source.kind
    if config.hand_source.reader is None:
        return [f"hand: {kind} (no tracker configured)"]
    try:
        hand = open_tracked_hand(config)
    except (RobotIOError, OSError) as exc:
        return [f"hand: NOT OK — {exc}"]
    try:
        time.sleep(listen_s)
        return [_judge_hand(kind, hand, listen_s, config.loop.staleness_limit_s)]
    finally:
        hand.close()


def _judge_hand(kind: str, hand: TrackedHand, listen_s: float, staleness_limit_s: float) -> str:
    """One line on what the tracker sent while we listened: NOT OK unless it sent positions, fresh
    enough for the control loop (``staleness_limit_s``), with valid time stamps."""
    received, dropouts, invalid = hand.received, hand.dropouts, hand.invalid
    heard = f"{received} samples in {listen_s:g} s ({dropouts} occluded or invalid)"
    if received == 0:
        return f"hand: NOT OK — {kind} source open but no sample in {listen_s:g} s"
    if invalid:
        return (f"hand: NOT OK — {invalid} of {received} samples were refused, the latest as "
                f"{hand.refusal} (also refused: a non-finite time stamp, a position more than "
                f"{PLAUSIBLE_RANGE_M:g} m from the robot base): check the units, the sender's clock "
                "and the marker's labelling")
    valid_age = hand.valid_age()
    if valid_age is None:
        return (f"hand: NOT OK — all {received} samples occluded (no marker position): is the "
                "hand marker visible to the tracker?")
    if valid_age > staleness_limit_s:
        return (f"hand: NOT OK — the newest position is {valid_age:.3f} s old (staleness_limit_s "
                f"= {staleness_limit_s} s): the tracker's time stamps are not on this machine's "
                f"clock, or it stopped; {heard}")
    detail = hand.detail()
    return (f"hand: {kind}, {received / listen_s:.0f} samples/s, newest {1e3 * valid_age:.0f} ms "
            f"old, {dropouts} occluded" + (f"; {detail}" if detail else ""))

"""The kinematic mock arm and the safety limiter."""

from __future__ import annotations

import re

import numpy as np
import pytest

from robot_io.arms.arm import ArmState
from robot_io.arms.mock_arm import MockArm
from robot_io.clock import SimClock
from robot_io.config import ControllerConfig, SafetyLimits
from robot_io.control.safety import SafetyLimiter
from robot_io.errors import ArmFault
from robot_io.minimum_jerk import minimum_jerk


def streaming_arm(start=(0.4, 0.0, 0.3), **limits) -> tuple[MockArm, SimClock]:
    clock = SimClock(500)
    clock.start()
    arm = MockArm(clock, np.array(start), **limits)
    arm.begin_stream()
    return arm, clock


def test_a_target_is_reached_one_cycle_later():
    arm, clock = streaming_arm()
    target = np.array([0.40002, 0.0, 0.3])  # 10 mm/s after one 2 ms cycle: within 10 m/s²
    arm.command(target)
    np.testing.assert_allclose(arm.read_pose(), [0.4, 0.0, 0.3])  # same cycle: not yet
    clock.wait_next_cycle()
    np.testing.assert_allclose(arm.read_pose(), target)


def ramp(clock: SimClock, arm: MockArm, acceleration: float, top_speed: float, cycles: int) -> None:
    """Command a straight move along x that accelerates at ``acceleration`` up to ``top_speed``."""
    x, v = arm.read_pose()[0], 0.0
    for _ in range(cycles):
        v = min(top_speed, v + acceleration * clock.period)
        x += v * clock.period
        arm.command(np.array([x, 0.0, 0.3]))
        clock.wait_next_cycle()


def test_a_feasible_stream_is_followed_exactly():
    arm, clock = streaming_arm()
    ramp(clock, arm, acceleration=4.0, top_speed=0.5, cycles=200)
    assert arm.state is ArmState.STREAMING
    assert np.linalg.norm(arm.velocity) == pytest.approx(0.5)


@pytest.mark.parametrize("acceleration,top_speed,message", [
    (50.0, 0.5, r"needs 50.00 m/s² \(max_acceleration = 10.0 m/s²\)"),
    (9.0, 3.0, r"needs 1.51. m/s \(max_speed = 1.5 m/s\)"),
])
def test_a_target_beyond_the_arm_limits_trips_a_fault(acceleration, top_speed, message):
    arm, clock = streaming_arm()
    ramp(clock, arm, acceleration, top_speed, cycles=1)
    with pytest.raises(ArmFault, match="following error"):
        ramp(clock, arm, acceleration, top_speed, cycles=500)
    assert arm.state is ArmState.FAULT
    assert re.search(message, arm.fault)
    assert not arm.is_moving


def test_stop_decelerates_to_rest_and_refuses_further_targets():
    arm, clock = streaming_arm(stop_deceleration=10.0)
    ramp(clock, arm, acceleration=4.0, top_speed=0.5, cycles=200)
    arm.stop()
    assert arm.state is ArmState.STOPPING
    cycles = 0
    while arm.is_moving:
        clock.wait_next_cycle()
        cycles += 1
    assert cycles == pytest.approx(0.5 / 10.0 / clock.period, abs=2)
    assert arm.state is ArmState.STOPPED
    with pytest.raises(ArmFault, match="stopped"):
        arm.command(np.array([0.4, 0.0, 0.3]))
    arm.begin_stream()  # at rest again: streaming may resume
    assert arm.state is ArmState.STREAMING


def test_injected_fault_halts_and_is_reported():
    arm, _ = streaming_arm()
    arm.inject_fault("protective stop")
    assert arm.state is ArmState.FAULT and arm.fault == "protective stop"
    with pytest.raises(ArmFault, match="protective stop"):
        arm.command(np.array([0.4, 0.0, 0.3]))
    with pytest.raises(ArmFault, match="fault"):
        arm.begin_stream()


def test_limiter_never_leaves_the_box_and_keeps_the_caps_inside_it():
    limits = SafetyLimits()
    low, high = np.array(limits.workspace_min), np.array(limits.workspace_max)
    limiter = SafetyLimiter(limits, dt=0.002)
    limiter.reset((low + high) / 2)
    rng = np.random.default_rng(0)
    out, flags = [], []
    for _ in range(50):  # wild targets, most far outside the box, each held for 100 cycles
        wild = rng.uniform(low - 1.0, high + 1.0)
        for _ in range(100):
            sent, flag = limiter.limit(wild + rng.normal(0, 0.05, 3))
            out.append(sent)
            flags.append(flag)
    out = np.array(out)
    assert np.all(out >= low) and np.all(out <= high)
    velocity = np.diff(out, axis=0) / 0.002
    assert np.linalg.norm(velocity, axis=1).max() <= limits.max_speed + 1e-9
    accel = np.linalg.norm(np.diff(velocity, axis=0), axis=1) / 0.002
    inside = ~np.array([f.workspace for f in flags])[2:]  # at the box wall the box wins over the cap
    assert accel[inside].max() <= limits.max_acceleration + 1e-6
    assert any(f.workspace for f in flags) and any(f.speed for f in flags)


def test_limiter_passes_a_trajectory_within_the_caps_unchanged(start, goal):
    """A 1 s minimum-jerk reach of 0.45 m peaks at 0.84 m/s and 2.6 m/s²: under both caps."""
    limiter = SafetyLimiter(SafetyLimits(), dt=0.002)
    limiter.reset(start)
    t = np.arange(1, 600) * 0.002
    for target in minimum_jerk(start, goal, 1.0, t)[0]:
        sent, flags = limiter.limit(target)
        assert not flags.any()
        np.testing.assert_allclose(sent, target, atol=1e-12)


def test_scene_points_outside_the_workspace_are_refused():
    # the numbers as a person writes them, never np.float64(1.5)
    with pytest.raises(ValueError, match=re.escape(
            "scene.handover_point = (1.5, 0, 0.3) is outside the workspace box [(0.1, -0.6, 0.05), "
            "(0.9, 0.6, 0.8)]")):
        ControllerConfig.model_validate({"scene": {"handover_point": (1.5, 0.0, 0.3)}})
    with pytest.raises(ValueError, match=r"workspace_min\[2\] = 0.9 must be below"):
        SafetyLimits(workspace_min=(0.1, -0.6, 0.9))

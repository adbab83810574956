"""The UR backend with ur_rtde's real client against the stand-in controller (one address per test).

What the controller received is read back from the stand-in and asserted on.
"""

from __future__ import annotations

import contextlib
import json
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest
from support.hand_replay import TRACKER, Replay
from ur_helpers import (
    MOVEL,
    SERVO_STOP,
    SERVOL,
    SET_WATCHDOG,
    STOP_SCRIPT,
    commands,
    servo_targets,
    settled_servo_targets,
    standin,
)

from robot_io.arm import ArmState
from robot_io.config import ControllerConfig
from robot_io.devices import tracker_transform, ur_trial
from robot_io.errors import ArmFault
from robot_io.loop import Outcome
from robot_io.simulated_hand import Scenario, SimulatedHand
from robot_io.theta import Theta
from robot_io.udp_hand import UDPHand
from robot_io.ur_arm import URArm
from robot_io.ur_standin.control import ControlClient

THETA = Theta(a=5.0, delta=-0.2, k=1.0)
STEP = np.array([0.0002, 0.0, 0.0])


def ur_config(host: str) -> ControllerConfig:
    config = ControllerConfig()
    return config.model_copy(update={"ur": config.ur.model_copy(update={"host": host})})


@contextlib.contextmanager
def connected_arm(host: str) -> Iterator[tuple[ControlClient, ControllerConfig, URArm]]:
    """A stand-in on ``host`` and a URArm connected to it; both ended afterwards."""
    config = ur_config(host)
    with standin(host) as control:
        arm = URArm(config.ur, config.safety)
        try:
            yield control, config, arm
        finally:
            arm.close()


def hand(config: ControllerConfig, seed: int = 0) -> SimulatedHand:
    return SimulatedHand(Scenario.STRAIGHTFORWARD, config.scene, config.hand, seed)


@pytest.mark.slow
def test_full_handover_from_the_cli_targets_follow_the_dmp_within_1mm(tmp_path):
    host = "127.0.0.101"
    samples = tmp_path / "samples.npz"
    with standin(host) as control:
        run = subprocess.run(
            [sys.executable, "-m", "app.cli", "simulate-trial", "--arm", "ur", "--ur-host", host,
             "--scenario", "perturbed", "--theta", "5,-0.2,15", "--seed", "2", "--json",
             "--samples", str(samples)],
            capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, run.stderr
        summary = json.loads(run.stdout)
        received = servo_targets(control)
        sequence = commands(control)
        state = control("state")
    assert summary["outcome"] == "completed" and summary["rate_hz"] == 125
    data = np.load(samples)
    dmp_path = data["x"][np.isfinite(data["commanded"][:, 0])]
    sent = np.array([xyz for _, xyz in received])
    assert len(sent) == len(dmp_path) > 100
    assert np.max(np.linalg.norm(sent - dmp_path, axis=1)) < 1e-3
    # the protocol around the stream: moveL to the start, watchdog, servoL…, servoStop, stop script
    assert sequence[:2] == [MOVEL, SET_WATCHDOG] and sequence[-2:] == [SERVO_STOP, STOP_SCRIPT]
    assert set(sequence[2:-2]) == {SERVOL}
    assert np.linalg.norm(np.array(state["pose"][:3]) - dmp_path[-1]) < 0.01


def aborted_by(control: ControlClient, config: ControllerConfig, arm: URArm, fault: str,
               reason: str, after_s: float = 0.6, **arguments):
    """A trial with the stand-in fault ``fault`` injected ``after_s`` into it; asserts it ended as an
    arm fault whose reason says ``reason``; returns (record, injected_at)."""
    injected = {}

    def later() -> None:
        time.sleep(after_s)
        injected["at"] = time.monotonic()
        control(fault, **arguments)

    timer = threading.Thread(target=later)
    timer.start()
    record = ur_trial(config, THETA, hand(config), arm)
    timer.join()
    assert record.summary.outcome is Outcome.ARM_FAULT
    assert reason in record.summary.reason
    return record, injected["at"]


def assert_recovers_for_the_next_trial(config: ControllerConfig, arm: URArm) -> None:
    arm.recover()
    assert arm.state is ArmState.IDLE
    second = ur_trial(config, THETA, hand(config, 1), arm)
    assert second.summary.outcome is Outcome.COMPLETED, second.summary.reason


@pytest.mark.slow
def test_protective_stop_aborts_the_trial_stops_streaming_and_recovers_for_the_next():
    with connected_arm("127.0.0.102") as (control, config, arm):
        _, at = aborted_by(control, config, arm, "protective_stop", "protective stop")
        late = [t for t, _ in servo_targets(control) if t > at + 0.05]
        assert late == [], f"{len(late)} servo targets sent after the protective stop"
        assert arm.state is ArmState.FAULT
        with pytest.raises(ArmFault, match="protective stop"):
            arm.move_to(config.scene.point("robot_start"))
        began = time.monotonic()
        assert_recovers_for_the_next_trial(config, arm)
        assert time.monotonic() - at >= 5.0 and time.monotonic() - began < 15.0
        assert "protective stop unlocked" in control("state")["events"]


@pytest.mark.slow
def test_dropped_socket_mid_trial_aborts_and_a_reconnect_serves_the_next_trial():
    with connected_arm("127.0.0.103") as (control, config, arm):
        record, _ = aborted_by(control, config, arm, "drop_sockets", "lost the RTDE connection")
        assert record.summary.duration_s < 0.6 + 0.2
        assert_recovers_for_the_next_trial(config, arm)


def test_a_target_outside_the_workspace_box_is_never_sent():
    with connected_arm("127.0.0.104") as (control, config, arm):
        arm.begin_stream()
        start = arm.read_pose()
        arm.command(start + STEP)  # a legal target: 0.025 m/s, 3.1 m/s² at 125 Hz
        outside = start.copy()
        outside[2] = config.safety.workspace_min[2] - 0.01
        with pytest.raises(ArmFault, match="outside the workspace box"):
            arm.command(outside)
        assert arm.state is ArmState.FAULT
        with pytest.raises(ArmFault):
            arm.command(start)  # nothing more is sent after the fault
        sent = [xyz for _, xyz in settled_servo_targets(control, expected=1)]
    assert len(sent) == 1 and sent[0] == pytest.approx(start + STEP)


def test_a_target_beyond_the_speed_cap_is_refused_and_a_far_start_pose_is_not_moved_to():
    with connected_arm("127.0.0.105") as (control, _, arm):
        far = arm.read_pose() + np.array([0.0, 0.9, 0.0])
        with pytest.raises(ArmFault, match="max_move_distance"):
            arm.move_to(far)
        arm.begin_stream()
        with pytest.raises(ArmFault, match="m/s"):
            arm.command(arm.read_pose() + np.array([0.05, 0.0, 0.0]))  # 6.25 m/s at 125 Hz
        assert settled_servo_targets(control, expected=0) == [] and MOVEL not in commands(control)


def test_check_devices_reports_versions_and_rate_and_moves_nothing(capsys):
    from app.cli import main

    host = "127.0.0.106"
    with standin(host, series="e") as control:
        code = main(["check-devices", "--ur-host", host])
        out = capsys.readouterr().out
        assert not {MOVEL, SERVOL, SET_WATCHDOG} & set(commands(control))
        pose_after = control("state")["pose"]
    assert code == 0, out
    assert "PolyScope 5.11.1.108318" in out and "500 Hz" in out and "gripper: none" in out
    assert pose_after[:3] == pytest.approx([0.35, -0.35, 0.35])


@pytest.mark.slow
def test_a_stale_hand_source_stops_the_arm():
    """The tracker (UDP/JSON at 100 Hz) goes silent mid-reach: the loop stops, servoL stops, the
    controller is told servoStop."""
    host = "127.0.0.108"
    config = ur_config(host)
    source = config.hand_source.model_copy(update={
        "kind": "udp", "udp_host": host, "udp_port": 0, "units_to_m": TRACKER.units_to_m,
        "rotation": tuple(map(tuple, TRACKER.rotation)), "translation": tuple(TRACKER.translation)})
    config = config.model_copy(update={"hand_source": source})
    with standin(host) as control:
        arm = URArm(config.ur, config.safety)
        tracker = UDPHand(config.hand_source, tracker_transform(config))
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

        def send(xyz: np.ndarray) -> None:
            sender.sendto(json.dumps(dict(zip("xyz", xyz.tolist(), strict=True))).encode(),
                          tracker.address)

        replay = Replay(hand(config), send, 100.0, stop_after=0.8).start()
        try:
            tracker.wait_for_sample(2.0, config.loop.staleness_limit_s)
            record = ur_trial(config, THETA, tracker, arm)
            silent_at = replay.began + 0.8
        finally:
            replay.stop()
            tracker.close()
            sender.close()
            arm.close()
        received = control("received")["received"]
    assert record.summary.outcome is Outcome.TRACKER_LOST, record.summary.reason
    servo_times = [t for t, command, _ in received if command == SERVOL]
    stop_times = [t for t, command, _ in received if command == SERVO_STOP]
    limit = config.loop.staleness_limit_s
    assert servo_times[-1] < silent_at + limit + 0.05  # no target once the hand is stale
    assert stop_times and stop_times[0] >= servo_times[-1]
    assert stop_times[0] < silent_at + limit + 0.1


@pytest.mark.slow
def test_a_stalled_controller_aborts_the_trial_within_a_few_cycles():
    with connected_arm("127.0.0.111") as (control, config, arm):
        record, _ = aborted_by(control, config, arm, "stall", "sent no new state", after_s=0.5,
                               seconds=1.0)
        stop = record.summary.stop_commanded_s
        assert stop is not None and record.summary.duration_s < 0.5 + 0.1 + 0.1
        assert_recovers_for_the_next_trial(config, arm)


def test_an_emergency_stop_is_a_fault_that_recover_refuses_until_released():
    with connected_arm("127.0.0.112") as (control, _, arm):
        control("emergency_stop")
        time.sleep(0.1)
        assert arm.state is ArmState.FAULT and "emergency stop" in arm.fault
        with pytest.raises(ArmFault, match="emergency stop still engaged"):
            arm.recover()
        control("release_emergency_stop")
        time.sleep(0.1)  # the next state package carries it
        arm.recover()
        assert arm.state is ArmState.IDLE


def test_check_devices_says_in_plain_words_when_no_controller_answers(capsys):
    from app.cli import main

    code = main(["check-devices", "--ur-host", "127.0.0.113"])  # nothing listens there
    out = capsys.readouterr().out
    assert code == 1
    assert "arm: NOT OK — cannot connect to the UR controller at 127.0.0.113" in out

"""The UR backend with ur_rtde's real client against the stand-in controller (one address per test).

What the controller received is read back from the stand-in and asserted on.
"""

from __future__ import annotations

import contextlib
import json
import socket
import subprocess
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest
from support.hand_replay import TRACKER, Replay
from support.priority import REALTIME_CLI, realtime_threads
from support.repeats import starved, unless_starved
from support.ur import (
    MOVEL,
    SERVO_STOP,
    SERVOL,
    SET_WATCHDOG,
    STOP_SCRIPT,
    commands,
    servo_targets,
    servo_targets_once_stopped,
    settled_servo_targets,
    standin,
)
from support.waiting import wait_for

from robot_io.arms.arm import ArmState
from robot_io.arms.ur_arm import EMERGENCY_STOPPED_BITS, URArm
from robot_io.config import ControllerConfig
from robot_io.control.loop import Outcome
from robot_io.devices import arm_trial, tracker_transform
from robot_io.errors import ArmFault
from robot_io.hands.simulated_hand import Scenario, SimulatedHand
from robot_io.hands.udp_hand import UDPHand
from robot_io.standins.ur.control import ControlClient
from robot_io.standins.ur.standin import DASHBOARD_PORT, RTDE_PORT
from robot_io.theta import Theta

# real processes and sockets on the clock: `make soak` repeats them
pytestmark = [pytest.mark.soak, pytest.mark.standin]

THETA = Theta(a=5.0, delta=-0.2, k=1.0)
STEP = np.array([0.0002, 0.0, 0.0])


#: For the tests whose subject is not the controller's watchdog, which stops the script when no
#: target comes for 1/watchdog_hz s (0.1 s by default): a test streaming at normal priority on a
#: loaded machine (the loop, and the ur_rtde worker process that sends its targets) can be starved
#: longer than that (seen under a CPU hog: the first target never recorded, the script already
#: stopped; a trial ending "watchdog" before the fault it injects): 100 s instead.
PATIENT_WATCHDOG_HZ = 0.01


def ur_config(host: str, **ur) -> ControllerConfig:
    config = ControllerConfig()
    return config.model_copy(update={"ur": config.ur.model_copy(update={"host": host, **ur})})


@contextlib.contextmanager
def connected_arm(**ur) -> Iterator[tuple[ControlClient, ControllerConfig, URArm]]:
    """A stand-in on a free address and a URArm connected to it (``ur``: [ur] settings); both ended
    afterwards. The arm's threads (ur_rtde's receiver, the control worker, the loop) run under
    SCHED_FIFO where the OS allows it, as in a rig with ``[loop] realtime_priority``: at normal
    priority in a loaded suite the receiver was starved for more than STATE_SILENCE_S while the loop
    ran, and the trial after a recovery ended "no new state" (CI twice; beside the heaviest tests,
    with the stand-in's longest gap between cycles 9 ms)."""
    with standin() as ur_standin, realtime_threads():
        config = ur_config(ur_standin.host, **ur)
        arm = URArm(config.ur, config.safety)
        try:
            yield ur_standin.control, config, arm
        finally:
            arm.close()


def hand(config: ControllerConfig, seed: int = 0) -> SimulatedHand:
    return SimulatedHand(Scenario.STRAIGHTFORWARD, config.scene, config.hand, seed)


@pytest.mark.slow
def test_full_handover_from_the_cli_targets_follow_the_dmp_within_1mm(tmp_path):
    samples = tmp_path / "samples.npz"

    def attempt():  # a fresh stand-in each: its record is the run's
        with standin() as ur:
            control = ur.control
            run = subprocess.run(
                [*REALTIME_CLI, "simulate-trial", "--arm", "ur", "--ur-host", ur.host,
                 "--scenario", "perturbed", "--theta", "5,-0.2,15", "--seed", "2", "--json",
                 "--samples", str(samples)],
                capture_output=True, text=True, timeout=300)  # a ceiling for a hung run
            if run.returncode != 0 and starved(run.stderr):
                return None, run.stderr.strip().splitlines()[-1]
            assert run.returncode == 0, run.stderr
            return (json.loads(run.stdout), servo_targets_once_stopped(control),
                    commands(control), control("state")), None

    summary, received, sequence, state = unless_starved("simulate-trial", attempt)
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
               reason: str, after_targets: int = 75, **arguments):
    """A trial with the stand-in fault ``fault`` injected once the stand-in has received
    ``after_targets`` servo targets (75: 0.6 s into the reach at 125 Hz, counted, not timed);
    asserts it ended as an arm fault whose reason says ``reason``; returns the record, when it was
    injected, this trial's targets received by then, and the targets the stand-in had received
    before this trial (an earlier attempt's: its record of them is not cleared).

    A trial that ended before the injection (the machine's load starved the stand-in: "no new
    state" with nothing injected) says nothing about the fault: the arm is recovered and the trial
    run again (support.repeats)."""

    def attempt():
        record, injected = _injected_trial(control, config, arm, fault, after_targets, arguments)
        if injected:
            return (record, injected), None
        if arm.state is ArmState.FAULT:
            arm.recover()
        return None, (f"{record.summary.outcome.value} ({record.summary.reason}) before "
                      f"{after_targets} targets")

    record, injected = unless_starved(f"the trial for the injected {fault!r}", attempt)
    assert record.summary.outcome is Outcome.ARM_FAULT, record.summary.reason
    assert reason in record.summary.reason
    return record, injected["at"], injected["targets"], injected["earlier"]


def _injected_trial(control: ControlClient, config: ControllerConfig, arm: URArm, fault: str,
                    after_targets: int, arguments: dict):
    """One trial, ``fault`` injected at ``after_targets`` unless the trial ended first; the record
    and, if it was injected, when and at how many targets (an empty dict if not)."""
    earlier = len(servo_targets(control))
    injected: dict = {}
    decided = threading.Lock()  # the injection, or the trial's end: whichever comes first
    over = threading.Event()

    def later() -> None:
        targets = wait_for(
            lambda: over.is_set() or ((n := len(servo_targets(control)) - earlier) >= after_targets
                                      and n),
            f"{after_targets} servo targets of this trial at the stand-in (or the trial's end)",
            timeout=120.0)
        with decided:
            if over.is_set():
                return
            injected.update(targets=targets, at=time.monotonic(), earlier=earlier)
            control(fault, **arguments)

    timer = threading.Thread(target=later)
    timer.start()
    try:
        record = arm_trial(config, THETA, hand(config), arm)
    finally:
        with decided:
            over.set()
        timer.join()
    return record, injected


#: Loop cycles from the cycle whose target made the stand-in's count reach the injection point to
#: the trial's last cycle. A count of cycles, not a time, and a bound kept with its reason: the fault
#: is in the stand-in's next state package (one controller cycle) and the loop reads the state every
#: cycle, so 2-3 cycles idle; the margin is for the targets in flight between the loop, the worker
#: process and the stand-in when the injection counted them, which grows when those processes are
#: starved at once (two suites and a CPU hog on 2 cores). A loop that ignored the fault would stream
#: on to the end of the reach: 100+ cycles more.
STOP_WITHIN_CYCLES = 25


def cycles_after(record, targets: int) -> int:
    """Loop cycles after the one that commanded the ``targets``-th servo target."""
    commanded = np.flatnonzero(np.isfinite(record.samples["commanded"][:, 0]))
    return len(record.samples["t"]) - 1 - int(commanded[targets - 1])


def assert_recovers_for_the_next_trial(control: ControlClient, config: ControllerConfig,
                                      arm: URArm) -> None:
    """recover() clears the fault and the next trial completes (repeated, recovered again, while
    the machine starves it: support.repeats)."""

    def attempt():
        arm.recover()
        assert arm.state is ArmState.IDLE
        second = arm_trial(config, THETA, hand(config, 1), arm)
        state = control("state")
        reason = (f"{second.summary.reason}; the stand-in's longest gap between cycles "
                  f"{state['longest_gap_s']:.3f} s, its last events {state['events'][-5:]}")
        return (second, reason), (reason if starved(second.summary.reason) else None)

    second, reason = unless_starved("the trial after recover()", attempt)
    assert second.summary.outcome is Outcome.COMPLETED, reason


@pytest.mark.slow
def test_protective_stop_aborts_the_trial_stops_streaming_and_recovers_for_the_next():
    with connected_arm(watchdog_hz=PATIENT_WATCHDOG_HZ) as (control, config, arm):
        record, at, targets, earlier = aborted_by(control, config, arm, "protective_stop",
                                                  "protective stop")
        received = servo_targets_once_stopped(control)[earlier:]  # the loop's stop ended the script
        # the stand-in got no target the loop did not command (it records none once the stop has
        # ended the script, so one in flight then is not recorded), and the loop stopped commanding
        assert len(received) <= np.isfinite(record.samples["commanded"][:, 0]).sum()
        assert cycles_after(record, targets) <= STOP_WITHIN_CYCLES
        assert arm.state is ArmState.FAULT
        with pytest.raises(ArmFault, match="protective stop"):
            arm.move_to(config.scene.point("robot_start"))
        assert_recovers_for_the_next_trial(control, config, arm)  # recover() raises past its 15 s timeout
        assert time.monotonic() - at >= 5.0  # the controller's 5 s rule (load only adds to it)
        assert "protective stop unlocked" in control("state")["events"]


@pytest.mark.slow
def test_dropped_socket_mid_trial_aborts_and_a_reconnect_serves_the_next_trial():
    with connected_arm(watchdog_hz=PATIENT_WATCHDOG_HZ) as (control, config, arm):
        record, _, targets, _ = aborted_by(control, config, arm, "drop_sockets",
                                           "lost the RTDE connection")
        assert cycles_after(record, targets) <= STOP_WITHIN_CYCLES
        assert_recovers_for_the_next_trial(control, config, arm)


def test_a_target_outside_the_workspace_box_is_never_sent():
    with connected_arm(watchdog_hz=PATIENT_WATCHDOG_HZ) as (control, config, arm):
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
        sent = [xyz for _, xyz in settled_servo_targets(control, arm, expected=1)]
    assert len(sent) == 1 and sent[0] == pytest.approx(start + STEP)


def test_a_target_beyond_the_speed_cap_is_refused_and_a_far_start_pose_is_not_moved_to():
    with connected_arm(watchdog_hz=PATIENT_WATCHDOG_HZ) as (control, _, arm):
        far = arm.read_pose() + np.array([0.0, 0.9, 0.0])
        with pytest.raises(ArmFault, match="max_move_distance"):
            arm.move_to(far)
        arm.begin_stream()
        with pytest.raises(ArmFault, match="m/s"):
            arm.command(arm.read_pose() + np.array([0.05, 0.0, 0.0]))  # 6.25 m/s at 125 Hz
        assert settled_servo_targets(control, arm, expected=0) == [] and MOVEL not in commands(control)


def test_close_leaves_no_client_connection_open_on_the_controller():
    """``URArm.close`` releases every ur_rtde client the arm opened: the receive interface (by
    dropping it: its destructor disconnects), the dashboard client, the control worker's."""
    with standin() as ur_standin:
        config = ur_config(ur_standin.host)
        arm = URArm(config.ur, config.safety)

        def clients() -> dict[str, int]:
            """Open client connections by port number."""
            return ur_standin.control("clients")["clients"]

        opened = clients()
        arm.close()
        wait_for(lambda: not any(clients().values()), "the arm's client connections to end",
                 seen=clients)
    # RTDE: the receive interface's and the control worker's; the dashboard's
    assert opened[str(RTDE_PORT)] == 2 and opened[str(DASHBOARD_PORT)] >= 1, opened


def test_check_devices_reports_versions_and_rate_and_moves_nothing(capsys):
    from app.cli import main

    with standin(series="e") as ur:
        control = ur.control
        code = main(["check-devices", "--ur-host", ur.host])
        out = capsys.readouterr().out
        assert not {MOVEL, SERVOL, SET_WATCHDOG} & set(commands(control))
        pose_after = control("state")["pose"]
    assert code == 0, out
    assert "PolyScope 5.11.1.108318" in out and "500 Hz" in out and "gripper: none" in out
    assert pose_after[:3] == pytest.approx([0.35, -0.35, 0.35])


#: Servo targets into the reach (0.2 s at 125 Hz) when the stale-hand test's tracker goes silent.
MID_REACH_TARGETS = 25


@pytest.mark.slow
def test_a_stale_hand_source_stops_the_arm():
    """The tracker (UDP/JSON at 100 Hz) goes silent mid-reach: the loop stops, servoL stops, the
    controller is told servoStop."""
    with standin() as ur, realtime_threads():  # as connected_arm's
        config = ur_config(ur.host)
        source = config.hand_source.as_kind("udp", **{
            "udp_host": ur.host, "units_to_m": TRACKER.units_to_m,
            "rotation": tuple(map(tuple, TRACKER.rotation)),
            "translation": tuple(TRACKER.translation)}).model_copy(update={"udp_port": 0})
        config = config.model_copy(update={"hand_source": source})
        arm = URArm(config.ur, config.safety)
        tracker = UDPHand(config.hand_source, tracker_transform(config), config.hand.max_speed)
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

        def send(xyz: np.ndarray) -> None:
            sender.sendto(json.dumps(dict(zip("xyz", xyz.tolist(), strict=True))).encode(),
                          tracker.address)

        replay = Replay(hand(config), send, 100.0).start()
        over = threading.Event()

        def silence_mid_reach() -> None:
            """The tracker goes silent once the reach is under way (counted at the controller,
            not timed: a replay stopped after 0.8 s went silent before a loaded machine's move to
            the start had ended, and the trial was lost before its first target)."""
            wait_for(lambda: over.is_set() or len(servo_targets(ur.control)) >= MID_REACH_TARGETS,
                     f"{MID_REACH_TARGETS} servo targets at the stand-in (or the trial's end)")
            replay.stop()

        silencer = threading.Thread(target=silence_mid_reach)
        try:
            tracker.wait_for_sample(30.0, config.loop.staleness_limit_s)  # a ceiling
            silencer.start()
            record = arm_trial(config, THETA, tracker, arm)
        finally:
            over.set()
            if silencer.is_alive():
                silencer.join()
            replay.stop()
            tracker.close()
            sender.close()
            arm.close()
        servo_targets_once_stopped(ur.control)
        received = ur.control("received")["received"]
    assert record.summary.outcome is Outcome.TRACKER_LOST, record.summary.reason
    # in the loop's own clock and the hand's own stamps: every target was commanded on a hand sample
    # at most staleness_limit_s old, and the trial ended on the first cycle it was older
    samples, limit = record.samples, config.loop.staleness_limit_s
    commanded = np.isfinite(samples["commanded"][:, 0])
    assert np.all(samples["t"][commanded] - samples["hand_t"][commanded] <= limit)
    assert record.summary.stop_commanded_s - record.summary.last_hand_sample_s > limit
    # at the controller: exactly those targets, then servoStop
    sequence = [command for _, command, _ in received]
    assert sequence.count(SERVOL) == commanded.sum()
    assert SERVO_STOP in sequence and SERVOL not in sequence[sequence.index(SERVO_STOP):]


@pytest.mark.slow
def test_a_stalled_controller_aborts_the_trial_within_a_few_cycles():
    """The next trial is started once the controller has stopped stalling, as an experimenter
    who inspected the cause would (recover() called while the stand-in was still stalled, which
    the trial's stop path can outlast under load, left the next moveL refused: CI, today)."""
    with connected_arm(watchdog_hz=PATIENT_WATCHDOG_HZ) as (control, config, arm):
        record, _, targets, _ = aborted_by(control, config, arm, "stall", "sent no new state",
                                           after_targets=62, seconds=1.0)
        assert record.summary.stop_commanded_s is not None
        # STATE_SILENCE_S of silence (0.1 s: 13 cycles at 125 Hz), then as any fault
        assert cycles_after(record, targets) <= 13 + STOP_WITHIN_CYCLES
        wait_for(lambda: not control("state")["stalled"], "the stand-in's stall to end",
                 seen=lambda: control("state")["events"][-3:])
        assert_recovers_for_the_next_trial(control, config, arm)


def test_an_emergency_stop_is_a_fault_that_recover_refuses_until_released():
    with connected_arm() as (control, _, arm):
        control("emergency_stop")
        wait_for(lambda: arm.state is ArmState.FAULT, "the emergency stop in the arm's state",
                 seen=lambda: arm.state)
        assert "emergency stop" in arm.fault
        with pytest.raises(ArmFault, match="emergency stop still engaged"):
            arm.recover()
        control("release_emergency_stop")
        wait_for(lambda: not any(arm._bits("getSafetyStatusBits") >> bit & 1
                                 for bit in EMERGENCY_STOPPED_BITS),
                 "the release in the controller's state package",
                 seen=lambda: f"safety status bits {arm._bits('getSafetyStatusBits'):b}")
        arm.recover()
        assert arm.state is ArmState.IDLE


def test_check_devices_says_in_plain_words_when_no_controller_answers(capsys):
    from app.cli import main

    code = main(["check-devices", "--ur-host", "127.0.0.113"])  # nothing listens there
    out = capsys.readouterr().out
    assert code == 1
    assert "arm: NOT OK — cannot connect to the UR controller at 127.0.0.113" in out


def test_a_move_to_the_start_right_after_a_stop_waits_for_the_script_a_late_reader_still_reports():
    """Issue 38 item 3: after a trial's stop (servoStop, stopScript) the next prepare's moveL was
    refused ("the controller did not accept the moveL") when the arm's RTDE reader still reported
    the program running: the script was not re-uploaded, and ur_rtde refuses a command while the
    controller's runtime state is stopped. A reader 0.5 s late (a loaded host) reproduces it every
    time; the move now asks the control interface itself whether its script runs."""
    with connected_arm(watchdog_hz=PATIENT_WATCHDOG_HZ) as (control, _, arm):
        arm.begin_stream()
        start = arm.read_pose()
        arm.command(start + STEP)
        control("lag_readers", seconds=0.5)
        arm.stop()  # as at the end of a trial: servoStop, then stopScript
        wait_for(lambda: control("state")["program"] is None, "the stand-in's script to end",
                 seen=lambda: f"events {control('state')['events'][-3:]}, last commands received "
                              f"{commands(control)[-5:]}, control process alive "
                              f"{arm._control.alive} (exit code {arm._control.process.exitcode})")
        arm.move_to(start + 10 * STEP)
        control("lag_readers", seconds=0.0)
        moves = commands(control).count(MOVEL)
        pose = control("state")["pose"]
    assert moves == 1
    assert np.linalg.norm(np.asarray(pose[:3]) - (start + 10 * STEP)) < 1e-3


def test_a_control_process_that_died_is_stopped_from_the_dashboard_and_replaced_for_the_next_move(
        caplog):
    """The ur_rtde control process gone mid-stream (killed here; a crash inside ur_rtde alike): the
    stop cannot send servoStop or stopScript, says so, and stops the program through the dashboard
    server instead of leaving it to the controller's watchdog (100 s here); the next move to the
    start starts a new control process, uploads the script again, and arrives."""
    with connected_arm(watchdog_hz=PATIENT_WATCHDOG_HZ) as (control, _, arm):
        arm.begin_stream()
        start = arm.read_pose()
        arm.command(start + STEP)
        worker = arm._control.process
        worker.kill()
        worker.join(10.0)
        arm.stop()
        wait_for(lambda: control("state")["program"] is None, "the stand-in's script to end",
                 seen=lambda: control("state")["events"][-3:])
        events = control("state")["events"]
        arm.move_to(start + 10 * STEP)
        pose = control("state")["pose"]
        assert arm._control.process.pid != worker.pid
    assert "program rtde_control ended: dashboard stop" in events
    assert "the ur_rtde control process had exited (exit code -9)" in caplog.text
    assert "starting a new one" in caplog.text
    assert np.linalg.norm(np.asarray(pose[:3]) - (start + 10 * STEP)) < 1e-3

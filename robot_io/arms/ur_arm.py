"""The UR5 (CB-series 125 Hz, e-Series 500 Hz) over RTDE with ``ur_rtde``, behind the ``Arm`` protocol.

The control loop streams one Cartesian position per cycle; the backend sends it with ``servoL`` (the
TCP orientation held at what it was when the backend connected). Before anything is sent, the backend
checks it again, whatever the safety limiter upstream did: a target outside the workspace box, or one
that implies more than the speed or acceleration cap, is refused — never sent — and the arm faults.

* ``RTDEReceiveInterface`` (pose, speed, force, safety and program bits) and ``DashboardClient`` live
  in this process, ``RTDEControlInterface`` in a worker process (:mod:`robot_io.arms.ur_worker`). All are
  constructed in :meth:`URArm.connect`, before any real-time thread starts.
* Faults read every cycle: protective stop, emergency stop, lost RTDE connection, the control script
  no longer running (watchdog), the worker gone, no new controller state for 0.1 s (a stall). Each
  becomes ``ArmState.FAULT`` with a plain-words ``fault``; the loop then aborts the trial.
* Every value read from the controller is checked finite before it is used: a NaN or infinite
  pose, speed, force or time stamp is an arm fault (nothing more is sent), never a number to compute
  a motion from. The joint angles (``actual_q``) are only recorded and drawn, never used for a motion:
  they are passed on as read, and a non-finite one shows as missing.
* :meth:`recover` is the documented way back: reconnect what dropped, unlock a protective stop once
  the controller's 5 s have passed, re-upload the control script. The experimenter calls it (a
  protective stop is to be inspected before unlocking); it moves nothing.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any, Literal

import numpy as np

from robot_io.arms.arm import ArmKind, ArmSettings, ArmState, Backstop
from robot_io.arms.ur_config import URConfig
from robot_io.arms.ur_dashboard import DashboardStop
from robot_io.arms.ur_worker import ControlWorker
from robot_io.errors import ArmFault, ConfigError, MoveStopped
from robot_io.scene import SafetyLimits
from robot_io.vector import all_finite, norm

log = logging.getLogger(__name__)

#: What the backend subscribes to on the receive interface.
VARIABLES = ["timestamp", "actual_TCP_pose", "actual_q", "actual_TCP_speed", "actual_TCP_force",
             "robot_mode", "safety_mode", "runtime_state", "robot_status_bits", "safety_status_bits"]
PROTECTIVE_STOPPED_BIT = 2
EMERGENCY_STOPPED_BITS = (5, 6, 7)  # system, robot, any emergency stop
PROGRAM_RUNNING_BIT = 1
#: The controller refuses to unlock a protective stop within this many seconds of it.
UNLOCK_DELAY_S = 5.0
#: A move has arrived when the TCP is this close to its target [m] (and at rest).
ARRIVED_M = 5e-4
#: Speed [m/s] under which the TCP counts as at rest.
REST_SPEED = 1e-3
#: Relative slack on the speed and acceleration caps (floating point of the limiter upstream).
CAP_SLACK = 1e-6
#: Reads of the TCP pose and joint angles until both come from one state package.
SAME_STATE_TRIES = 3
#: While streaming, the controller's state time stamp must advance at least this often [s].
STATE_SILENCE_S = 0.1


class URArm:
    """A UR arm as the control loop's ``Arm``; call :meth:`close` when done."""

    #: The controller's last state time stamp, when this process saw it change, and when it last
    #: looked (``_state_silent``); set when streaming starts.
    _stamp: float
    _stamp_seen: float
    _checked_at: float

    def __init__(self, config: URConfig, limits: SafetyLimits) -> None:
        self.config, self.limits = config, limits
        self._state = ArmState.IDLE
        self._fault: str | None = None
        self._fault_at, self._fault_safety = 0.0, False
        self._low = np.asarray(limits.workspace_min, dtype=float)
        self._high = np.asarray(limits.workspace_max, dtype=float)
        self._worker: ControlWorker | None = None
        #: ur_rtde's receive interface and dashboard client (untyped modules): set by connect().
        self._receive: Any | None = None
        self._dashboard: Any | None = None
        self.period = 1.0 / 125
        self._last = np.zeros(3)
        self._last_velocity = np.zeros(3)
        self._joints = np.full(6, np.nan)
        #: How many times a recovery found the RTDE link down and connected it again: the links of
        #: the same RTDE server (a tool-output gripper's) dropped with it (``robot_io.rig.devices``).
        self.links_restored = 0
        self.connect()

    # The connections, between connect() and close(): the arm is not used outside them.
    @property
    def _host(self) -> str:
        assert self.config.host is not None, "[ur] host is set (the rig refuses arm.kind = 'ur' without it)"
        return self.config.host

    @property
    def _rtde(self) -> Any:
        assert self._receive is not None, "the UR arm is connected"
        return self._receive

    @property
    def _dash(self) -> Any:
        assert self._dashboard is not None, "the UR arm is connected"
        return self._dashboard

    @property
    def _control(self) -> ControlWorker:
        assert self._worker is not None, "the UR arm's control worker is running"
        return self._worker

    # -- connection ----------------------------------------------------------------------------
    def connect(self) -> None:
        """Connect receive, dashboard and control; learn the rate and the TCP orientation."""
        import dashboard_client
        import rtde_receive

        cfg, host = self.config, self._host
        try:
            self._receive = receive = rtde_receive.RTDEReceiveInterface(host, -1.0, VARIABLES)
            self._dashboard = dashboard = dashboard_client.DashboardClient(host)
            dashboard.connect(int(cfg.connect_timeout_s * 1000))
            self.polyscope_version: str = dashboard.polyscopeVersion()
        except RuntimeError as exc:
            raise ArmFault(f"cannot connect to the UR controller at {cfg.host}: {exc}") from exc
        self.rate_hz = 125 if self.polyscope_version.startswith("3.") else 500
        self.period = 1.0 / self.rate_hz
        try:
            self._start_worker()
        except ArmFault:
            self.close()  # leave no receive or dashboard connection behind
            raise
        try:
            self.orientation = self._finite(receive.getActualTCPPose()[3:], "TCP orientation")
        except ArmFault:
            self.close()
            raise
        log.info("connected to UR controller %s (PolyScope %s, %d Hz)", cfg.host,
                 self.polyscope_version, self.rate_hz)

    @property
    def version(self) -> str:
        return self.polyscope_version

    def describe(self) -> str:
        return f"UR at {self.config.host}, PolyScope {self.polyscope_version}, {self.rate_hz} Hz"

    def close(self) -> None:
        """Stop, end the control worker, disconnect. Safe to call twice."""
        self.stop()
        self._end_worker()
        # The receive interface is released by dropping it: its destructor disconnects. ur_rtde
        # 1.6 sleeps 0.5 s in disconnect() and again in the destructor, so disconnect() and then
        # the drop took the rig's close 1.0 s (measured against the stand-in, both times). This is
        # its one reference (the receiver thread is ur_rtde's own, inside the object).
        self._receive = None
        if self._dashboard is not None:
            self._dashboard.disconnect()
            self._dashboard = None

    def _reconnect(self) -> None:
        log.warning("reconnecting to the UR controller at %s", self.config.host)
        self._end_worker()
        if self._receive is not None and not self._receive.isConnected():
            self._receive.reconnect()
        self._dash.disconnect()
        self._dash.connect(int(self.config.connect_timeout_s * 1000))
        self._start_worker()

    @property
    def _worker_running(self) -> bool:
        return self._worker is not None and self._worker.alive

    @property
    def _worker_exit_code(self) -> int | None:
        """The exit code of a control process that has exited (None: none has, or there is none)."""
        return None if self._worker is None else self._worker.process.exitcode

    def _end_worker(self) -> None:
        if self._worker is not None:
            self._worker.close()
            self._worker = None

    def _start_worker(self) -> None:
        self._worker = ControlWorker(self._host, self.config.upper_range_registers,
                                     self.config.connect_timeout_s)

    # -- state ---------------------------------------------------------------------------------
    @property
    def state(self) -> ArmState:
        self._check()
        return self._state

    @property
    def fault(self) -> str | None:
        return self._fault

    @property
    def is_moving(self) -> bool:
        """True while the TCP moves; an unreadable (non-finite) speed counts as moving, and faults."""
        try:
            speed = norm(self._finite(self._rtde.getActualTCPSpeed()[:3], "TCP speed"))
        except ArmFault:
            return True
        return speed > REST_SPEED and self._rtde.isConnected()

    def read_pose(self) -> np.ndarray:
        """TCP position [m], base frame; a non-finite reading faults the arm (ArmFault). The joint
        angles of the same controller state are kept for :meth:`read_joints`: ur_rtde updates its
        state a whole package at a time, so a time stamp unchanged across both reads means one
        package (a new one in between is read again)."""
        receive = self._rtde
        for _ in range(SAME_STATE_TRIES):
            stamp = receive.getTimestamp()
            pose, joints = receive.getActualTCPPose(), receive.getActualQ()
            if receive.getTimestamp() == stamp:
                break
        self._joints = np.asarray(joints, dtype=float)
        return self._finite(pose[:3], "TCP position")

    def read_joints(self) -> np.ndarray:
        """The six joint angles [rad] (``actual_q``: base, shoulder, elbow, wrist 1–3) of the state
        the last :meth:`read_pose` read, as read."""
        return self._joints

    def read_force(self) -> np.ndarray:
        """Force at the TCP [N], base frame (CB-series: estimated from joint currents, ±10 N); a
        non-finite reading faults the arm (ArmFault)."""
        return self._finite(self._rtde.getActualTCPForce()[:3], "TCP force")

    def _finite(self, values, what: str) -> np.ndarray:
        """``values`` as an array, or an arm fault if any is NaN or infinite: a motion computed from
        it would be meaningless (``nan > limit`` is false, so every check would pass)."""
        array = np.asarray(values, dtype=float)
        if not all_finite(array):
            if self._state is not ArmState.FAULT:
                self._trip(f"the controller reported a non-finite {what} {array.tolist()}; nothing "
                           "is sent: check the controller and the RTDE link, then call recover()")
            raise ArmFault(self._fault or f"non-finite {what} {array.tolist()}")
        return array

    def _bits(self, name: str) -> int:
        return int(getattr(self._rtde, name)())

    def _check(self) -> None:
        """Turn whatever the controller reports into FAULT, in plain words."""
        if self._state is ArmState.FAULT:
            return
        host = self.config.host
        if not self._rtde.isConnected():
            self._trip(f"lost the RTDE connection to the controller at {host}; "
                       "call recover() to reconnect before the next trial")
            return
        safety = self._bits("getSafetyStatusBits")
        if any(safety >> bit & 1 for bit in EMERGENCY_STOPPED_BITS):
            self._trip("emergency stop: release the emergency stop button and power the arm on "
                       "again, then call recover()", safety=True)
        elif safety >> PROTECTIVE_STOPPED_BIT & 1:
            self._trip("protective stop: the controller stopped the arm (collision, following error "
                       "or a safety limit); inspect the cause, then call recover() — the controller "
                       f"unlocks no sooner than {UNLOCK_DELAY_S:g} s after the stop", safety=True)
        elif self._state is ArmState.STREAMING:
            if not self._worker_running:
                self._trip("the ur_rtde control process exited; call recover()")
            elif not self._program_running():
                self._trip("the control script stopped on the controller (watchdog: no target for "
                           f"more than {1 / self.config.watchdog_hz:.2f} s, or stopped from the "
                           "teach pendant); call recover()")
            elif self._state_silent():
                self._trip(f"the controller sent no new state for more than {STATE_SILENCE_S} s "
                           "(controller stalled or network congested); call recover()")

    def _state_silent(self) -> bool:
        """True when the controller's time stamp has not advanced for STATE_SILENCE_S while this
        process was there to see it (a non-finite time stamp faults the arm here).

        A check that comes more than half of STATE_SILENCE_S after the one before measures this
        process's own stall (the loop and ur_rtde's receive thread not scheduled: a loaded machine
        without real-time priority), not the controller's: the silence is counted afresh from it.
        A stall of this process is the controller's watchdog's to catch (no target for
        1/watchdog_hz stops the script), which it does whatever this process does."""
        now = time.monotonic()
        stalled = now - self._checked_at > STATE_SILENCE_S / 2
        self._checked_at = now
        try:
            stamp = float(self._finite(self._rtde.getTimestamp(), "state time stamp"))
        except ArmFault:
            return False
        if stamp != self._stamp or stalled:
            self._stamp, self._stamp_seen = stamp, now
        return now - self._stamp_seen > STATE_SILENCE_S

    @property
    def safety_stopped(self) -> bool:
        """In FAULT because the controller's safety system stopped the arm (protective or emergency
        stop): someone must inspect the cause before :meth:`recover`."""
        if self._state is not ArmState.FAULT:
            return False
        safety = self._bits("getSafetyStatusBits") if self._receive is not None else 0
        return self._fault_safety or bool(safety >> PROTECTIVE_STOPPED_BIT & 1) or any(
            safety >> bit & 1 for bit in EMERGENCY_STOPPED_BITS)

    def _trip(self, reason: str, safety: bool = False) -> None:
        log.error("UR arm fault: %s", reason)
        self._state, self._fault, self._fault_at = ArmState.FAULT, reason, time.monotonic()
        self._fault_safety = safety
        if self._dashboard is not None and self._rtde.isConnected():  # not on a dead link
            try:
                self._dashboard.addToLog(f"handover-lab: {reason}"[:200])
            except Exception:  # the pybind layer raises RuntimeError or boost errors
                log.warning("could not tell the dashboard about the fault", exc_info=True)

    # -- motion --------------------------------------------------------------------------------
    def _refuse_outside_box(self, pose: np.ndarray, what: str) -> None:
        if not (all_finite(pose) and (pose >= self._low).all() and (pose <= self._high).all()):
            raise ArmFault(f"{what} {np.round(pose, 4).tolist()} is outside the workspace box "
                           f"[{self.limits.workspace_min}, {self.limits.workspace_max}]; not sent")

    def _program_running(self) -> bool:
        """The program-running bit as the arm's RTDE reader last saw it (``_check`` reads it)."""
        return bool(self._bits("getRobotStatus") >> PROGRAM_RUNNING_BIT & 1)

    def _ensure_program(self) -> None:
        """The control script must run before any motion command; re-upload it if it stopped.

        The control interface's own view decides (ur_rtde refuses a command while the controller it
        reads reports the program stopped), not the reader's: a reader behind by a moment (a loaded
        host) still reported the script that a trial's stop had just ended, the script was not
        re-uploaded, and the next moveL was refused. The wait ends when both see it running, as
        ``_check`` reads the reader's bit while streaming.

        A control process that exited since the last motion (a crash inside ur_rtde, which it is
        there to contain) is replaced first: the arm is stopped, and the controller lost nothing."""
        if not self._worker_running:
            log.warning("the ur_rtde control process had exited (exit code %s): starting a new one",
                        self._worker_exit_code)
            self._end_worker()
            self._start_worker()
        if not self._control.call("isProgramRunning"):
            log.info("control script not running: re-uploading it")
            self._control.call("reuploadScript")
        deadline = time.monotonic() + self.config.connect_timeout_s
        while not (self._control.call("isProgramRunning") and self._program_running()):
            if time.monotonic() > deadline:
                raise ArmFault("the control script did not start after re-upload "
                               f"within {self.config.connect_timeout_s} s")
            time.sleep(0.01)

    def move_to(self, pose: np.ndarray, stop: threading.Event | None = None) -> None:
        """Bounded moveL to a start pose: inside the box, at most ``max_move_distance`` away. The
        move is asynchronous on the controller and watched every cycle, so that ``stop`` (set by a
        Stop) halts it with stopL and a fault is seen while it moves."""
        target = np.asarray(pose, dtype=float)
        if self.state in (ArmState.FAULT, ArmState.STREAMING):
            raise ArmFault(f"move_to refused while the arm is {self._state}"
                           + (f" ({self._fault})" if self._fault else ""))
        self._refuse_outside_box(target, "start pose")
        distance = float(np.linalg.norm(target - self.read_pose()))
        if distance > self.config.max_move_distance:
            raise ArmFault(f"start pose is {distance:.3f} m away (max_move_distance = "
                           f"{self.config.max_move_distance} m); jog the arm closer first")
        self._ensure_program()
        cfg = self.config
        deadline = (time.monotonic() + distance / cfg.move_speed
                    + cfg.move_speed / cfg.move_acceleration + 5.0)
        if not self._control.call("moveL", [*target, *self.orientation], cfg.move_speed,
                                 cfg.move_acceleration, True):
            raise ArmFault("the controller did not accept the moveL to the start pose (control "
                           f"script running: {self._control.call('isProgramRunning')}, safety "
                           f"status bits {self._bits('getSafetyStatusBits'):#x})")
        while np.linalg.norm(target - self.read_pose()) > ARRIVED_M or self.is_moving:
            if stop is not None and stop.is_set():
                self._control.call("stopL", cfg.stop_deceleration, False, timeout=2.0)
                raise MoveStopped("the move to the start pose was stopped on request")
            if self.state is ArmState.FAULT:
                raise ArmFault(self._fault)
            if time.monotonic() > deadline:
                raise ArmFault("moveL to the start pose was not completed in time")
            time.sleep(self.period)
        self._state = ArmState.IDLE

    def begin_stream(self) -> None:
        if self.state is ArmState.FAULT:
            raise ArmFault(f"arm in fault: {self._fault}")
        self._ensure_program()
        if not self._control.call("setWatchdog", self.config.watchdog_hz):
            raise ArmFault("the controller did not accept the watchdog")
        self._last = self.read_pose()
        self._last_velocity = np.zeros(3)
        self._stamp, self._stamp_seen = self._rtde.getTimestamp(), time.monotonic()
        self._checked_at = self._stamp_seen
        self._state = ArmState.STREAMING

    def command(self, target: np.ndarray) -> None:
        """Send one servo target, after the box, speed and acceleration checks."""
        if self.state is not ArmState.STREAMING:
            raise ArmFault(f"servo target refused: arm is {self._state}"
                           + (f" ({self._fault})" if self._fault else ""))
        target = np.asarray(target, dtype=float)
        try:
            self._refuse_outside_box(target, "servo target")
            self._refuse_too_fast(target)
        except ArmFault as exc:
            self._trip(str(exc))
            raise
        cfg = self.config
        self._control.servo([*target, *self.orientation], self.limits.max_speed,
                           self.limits.max_acceleration, self.period, cfg.servo_lookahead_s,
                           cfg.servo_gain)
        self._last_velocity = (target - self._last) / self.period
        self._last = target

    def _refuse_too_fast(self, target: np.ndarray) -> None:
        velocity = (target - self._last) / self.period
        speed = norm(velocity)
        acceleration = norm(velocity - self._last_velocity) / self.period
        if speed > self.limits.max_speed * (1 + CAP_SLACK):
            raise ArmFault(f"servo target needs {speed:.3f} m/s (max_speed = "
                           f"{self.limits.max_speed} m/s); not sent")
        if acceleration > self.limits.max_acceleration * (1 + CAP_SLACK):
            raise ArmFault(f"servo target needs {acceleration:.2f} m/s² (max_acceleration = "
                           f"{self.limits.max_acceleration} m/s²); not sent")

    def stop(self) -> None:
        """servoStop and end the control script (it is re-uploaded before the next motion), when
        streaming or after a fault met while streaming. Never raises."""
        if self._state not in (ArmState.STREAMING, ArmState.FAULT):
            return
        if self._state is ArmState.STREAMING:
            self._state = ArmState.STOPPING
        self._end_script()
        if self._state is ArmState.STOPPING:
            self._state = ArmState.STOPPED

    def _end_script(self) -> None:
        """servoStop, then stopScript even if servoStop failed. A script that outlives them (the
        control process gone or not answering, or ur_rtde gave up waiting) is stopped from the
        dashboard server; each of these is logged."""
        worker = self._worker
        if worker is None or not self._worker_running:
            log.error("stopping the UR arm: the ur_rtde control process had exited (exit code %s)",
                      self._worker_exit_code)
        else:
            for method, args in (("servoStop", (self.config.stop_deceleration,)),
                                 ("stopScript", ())):
                try:
                    worker.call(method, *args, timeout=1.0)  # False after a safety stop: checked below
                except ArmFault as exc:
                    log.error("stopping the UR arm: %s", exc)
            try:
                if not worker.call("isProgramRunning", timeout=1.0):
                    return
                log.error("stopping the UR arm: the control script still runs after stopScript")
            except ArmFault as exc:
                log.error("stopping the UR arm: %s", exc)
        self._stop_from_dashboard()

    def _stop_from_dashboard(self) -> None:
        """The program stopped by the dashboard server (port 29999), this process's own link."""
        if self._dashboard is None:
            return
        log.warning("stopping the control script from the dashboard server")
        try:
            self._dashboard.stop()
        except Exception as exc:  # the pybind layer raises RuntimeError or boost errors
            log.error("the dashboard stop failed too (%s): the controller's watchdog stops the "
                      "script", exc)

    def recover(self, timeout: float = 15.0) -> None:
        """The recovery path after a fault; moves nothing. Waits out the controller's 5 s rule."""
        if self.state is not ArmState.FAULT:
            return
        deadline = time.monotonic() + timeout
        link_down = not self._rtde.isConnected()
        if link_down or not self._worker_running:
            self._reconnect()
        self.links_restored += link_down
        safety = self._bits("getSafetyStatusBits")
        if any(safety >> bit & 1 for bit in EMERGENCY_STOPPED_BITS):
            raise ArmFault("emergency stop still engaged: release the button on the teach pendant")
        if safety >> PROTECTIVE_STOPPED_BIT & 1:
            self._unlock_protective_stop(deadline)
        self._state, self._fault = ArmState.IDLE, None
        self._ensure_program()
        log.info("UR arm recovered")

    def _unlock_protective_stop(self, deadline: float) -> None:
        wait = self._fault_at + UNLOCK_DELAY_S - time.monotonic()
        if wait > 0:
            log.info("waiting %.1f s before unlocking the protective stop (controller's rule)", wait)
            time.sleep(wait)
        self._dash.closeSafetyPopup()
        while True:
            try:
                self._dash.unlockProtectiveStop()
                return
            except RuntimeError as exc:
                if time.monotonic() > deadline:
                    raise ArmFault(f"the controller refused to unlock the protective stop: {exc}") from exc
                time.sleep(0.5)


class URArmKind(ArmKind):
    """``[arm] kind = "ur"``: a UR5 over RTDE at ``[ur] host`` (its settings: ``[ur]``). Moves it!"""

    tool_outputs = True
    fastest_rate_hz = 500  # an e-Series; a CB-series runs at 125 Hz, known once connected

    kind: Literal["ur"]

    def complete(self, settings: ArmSettings) -> None:
        """A UR's address is never assumed: on a lab network another robot may sit at any address."""
        if settings.ur.host is None:
            raise ConfigError('[ur] host is not set; [arm] kind = "ur" needs the UR controller\'s '
                              'address. Set it (e.g. host = "192.168.1.10"): it has no default, so no '
                              "robot at an assumed address is ever driven")

    def connect(self, settings: ArmSettings) -> URArm:
        return URArm(settings.ur, settings.safety)

    def backstop(self, settings: ArmSettings) -> Backstop:
        host = settings.ur.host
        assert host is not None, "ControllerConfig refuses arm.kind = 'ur' without [ur] host"
        return DashboardStop(host)

"""The rig's devices, opened once per rig process from the configuration, and the per-trial set the
cycle runs on (docs/controller.md, the rig process).

``[arm] kind``: ``mock`` (kinematic :class:`~robot_io.arms.mock_arm.MockArm`, made anew each trial on
the trial's clock, its force the simulated participant's pull) or ``ur`` (:class:`~robot_io.arms.ur_arm.URArm`
over ur_rtde, connected once). ``[hand_source] kind``: ``simulated`` (a seeded
:class:`~robot_io.hands.simulated_hand.SimulatedHand` per trial) or a tracker's (opened once, by the
reader its kind registers in :data:`robot_io.hands.config.HAND_SOURCES`).
``[gripper] kind``: ``tool_output`` (the UR's tool digital output), ``robotiq_socket`` (a Robotiq
2F-85 on its URCap's socket, :mod:`robot_io.grippers.robotiq`) or ``none``.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from robot_io.arms.arm import ArmState
from robot_io.arms.mock_arm import MockArm
from robot_io.arms.ur_arm import URArm
from robot_io.control.cycle import CycleDevices
from robot_io.control.trial import make_clock
from robot_io.devices import open_gripper, open_tracked_hand
from robot_io.errors import ArmFault, ConfigError, GripperFault
from robot_io.grippers.gripper import Gripper, NoGripper, ToolOutputGripper
from robot_io.grippers.kinds import GRIPPERS
from robot_io.hands.simulated_hand import Scenario, SimulatedHand
from robot_io.hands.simulated_pull import SimulatedPull
from robot_io.hands.tracked_hand import TrackedHand
from robot_io.rig.messages import DeviceReport, RigSpec

log = logging.getLogger(__name__)

#: A device whose close takes longer is named in the log [s].
SLOW_CLOSE_S = 1.0


def check_spec(spec: RigSpec) -> None:
    """Refuse combinations that cannot work, before anything is opened."""
    config = spec.config  # its device tables are whole (ControllerConfig._devices_complete)
    if config.hand_source.kind == "simulated" and spec.scenario is None:
        raise ConfigError("hand_source.kind = 'simulated' needs the session's scenario")
    if not spec.realtime and (config.arm.kind != "mock" or config.hand_source.kind != "simulated"):
        raise ConfigError("simulated time needs arm.kind = 'mock' and hand_source.kind = "
                          "'simulated'; real devices run on the wall clock")
    if not spec.realtime and config.gripper.kind != "none":
        raise ConfigError(f"simulated time needs gripper.kind = 'none', not {config.gripper.kind!r}: "
                          "a real gripper runs on the wall clock")


class RigDevices:
    """Everything the rig process owns; :meth:`close` releases it all."""

    def __init__(self, spec: RigSpec) -> None:
        check_spec(spec)
        self.spec = spec
        config = spec.config
        self.ur: URArm | None = None
        self.tracked: TrackedHand | None = None
        self.gripper: Gripper = NoGripper()
        self._mock_position = config.scene.point("robot_start")
        self._mock: MockArm | None = None
        try:
            if config.arm.kind == "ur":
                self.ur = URArm(config.ur, config.safety)
            if config.hand_source.reader is not None:
                self.tracked = open_tracked_hand(config)
            self.gripper = open_gripper(config)
        except BaseException:
            self.close()
            raise
        rate = self.ur.rate_hz if self.ur is not None else config.loop.rate_hz
        self.config = config.model_copy(update={"loop": config.loop.model_copy(
            update={"rate_hz": rate})})

    @property
    def _scenario(self) -> Scenario:
        """The simulated hand's scenario: the rig refuses a simulated hand without one (above)."""
        assert self.spec.scenario is not None, "a simulated hand source has the session's scenario"
        return self.spec.scenario

    def report(self) -> DeviceReport:
        config, ur, tracked = self.config, self.ur, self.tracked
        if ur is not None:
            arm_detail = f"UR at {config.ur.host}, PolyScope {ur.polyscope_version}, {ur.rate_hz} Hz"
        else:
            arm_detail = f"mock arm, {config.loop.rate_hz} Hz"
        source = config.hand_source
        hand_detail = (f"{tracked.PROTOCOL} {tracked.describe()}" if tracked is not None
                       else f"simulated hand ({self._scenario.value})")
        gripper_detail = GRIPPERS[config.gripper.kind].describe(config)
        return DeviceReport(arm=config.arm.kind, arm_detail=arm_detail,
                            polyscope_version=None if ur is None else ur.polyscope_version,
                            rate_hz=config.loop.rate_hz, hand_source=source.kind,
                            hand_detail=hand_detail, gripper=config.gripper.kind,
                            gripper_detail=gripper_detail)

    def for_trial(self, hand_seed: int) -> CycleDevices:
        """The arm, hand, gripper and a fresh clock for one trial."""
        config, spec = self.config, self.spec
        clock = make_clock(config, realtime=spec.realtime, realtime_priority=spec.realtime_priority)
        hand = self.tracked or SimulatedHand(self._scenario, config.scene, config.hand, hand_seed)
        arm: URArm | MockArm | None = self.ur
        if arm is None:
            if self._mock is not None:
                self._mock_position = self._mock.read_pose()
            pull = SimulatedPull(config.scene.point("hand_start") - config.scene.point("handover_point"),
                                 config.hand.pull_n, config.hand.grasp_delay_s)
            gripper = self.gripper

            def force(tcp: np.ndarray, speed: float) -> np.ndarray:
                now = clock.now()
                sample = hand.latest(now)
                return pull.force(now, None if sample is None else sample.position, tcp,
                                  gripper.holding, speed)

            arm = self._mock = MockArm(clock, self._mock_position, force=force)
        return CycleDevices(arm=arm, hand=hand, gripper=self.gripper, clock=clock)

    def recover(self, inspected: bool) -> str:
        """Clear the arm's fault and the gripper's; moves no joint. A safety stop (protective or
        emergency) is cleared only once someone inspected its cause; a refusal touches nothing.
        Returns what was done; raises ArmFault or GripperFault if refused."""
        arm = self.ur or self._mock
        faulted = arm if arm is not None and arm.state is ArmState.FAULT else None
        fault = None if faulted is None else faulted.fault
        if faulted is not None and faulted.safety_stopped and not inspected:
            raise ArmFault(f"not recovered: {fault} — inspect the cause, then recover from the "
                           "dashboard")
        gripper = self._recover_gripper()
        if faulted is None:
            return gripper or "the arm has no fault"
        restored = 0 if self.ur is None else self.ur.links_restored
        faulted.recover()
        # A tool-output gripper's link is the UR's RTDE server's: it dropped when the arm's did, and
        # only then is it connected again (a live link reconnected raced the server's release of
        # its registers: "One of the RTDE input registers are already in use")
        if isinstance(self.gripper, ToolOutputGripper) and self.ur is not None \
                and self.ur.links_restored > restored:
            self.gripper.reconnect()
            gripper = gripper or "the gripper's RTDE IO link connected again"
        return f"recovered from: {fault}" + (f"; {gripper}" if gripper else "")

    def _recover_gripper(self) -> str | None:
        """A gripper with a fault is connected again: a Robotiq's fault stays with its connection,
        whose state is unknown after it (one that lost its activation is activated again, which
        opens and closes its fingers once). None: it had no fault. Raises the GripperFault of the
        new connection if its cause remains (the URCap still silent)."""
        try:
            self.gripper.check()
        except GripperFault as fault:
            self.gripper.disconnect()
            self.gripper = open_gripper(self.spec.config)
            return f"gripper connected again after: {fault}"
        return None

    def stop_arm(self) -> None:
        """Stop the arm between trials (never raises)."""
        arm = self.ur or self._mock
        if arm is not None:
            arm.stop()

    def close(self) -> None:
        """Stop the arm, then release everything (never raises)."""
        for name, action in (("arm", self.stop_arm),
                             ("gripper", lambda: self.gripper.disconnect()),
                             ("hand source", lambda: _close(self.tracked)),
                             ("UR", lambda: _close(self.ur))):
            began = time.monotonic()
            try:
                action()
            except Exception:
                log.exception("closing the rig's %s failed", name)
            if (took := time.monotonic() - began) > SLOW_CLOSE_S:
                # the application kills a rig that is slow to exit after Shutdown: say where
                # the time went
                log.warning("closing the rig's %s took %.1f s", name, took)


def _close(device: TrackedHand | URArm | None) -> None:
    if device is not None:
        device.close()
